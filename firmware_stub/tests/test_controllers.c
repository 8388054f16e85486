/* Controller table: one entry per DBC id with its name, id and phase count; the controller state is
 * reset on a change of controller and on a rising enable edge (and kept otherwise); the frame's phase
 * count must match the entry. */
#include <stdint.h>
#include <string.h>

#include "fw_check.h"
#include "fw_fixture.h"
#include "hil_fw.h"
#include "hil_fw_dsvm.h"

#define TS_NS 100000u

static void test_table_entries(void)
{
    uint8_t id;
    for (id = 0u; id < HIL_FW_CTRL_COUNT; ++id) {
        const hil_fw_controller_t *c = hil_fw_controller_get(id);
        CHECK(c != NULL, "id %u has a table line", id);
        if (c == NULL) {
            continue;
        }
        CHECK(c->id == id, "entry %u carries id %u", id, c->id);
        CHECK(c->name != NULL && strcmp(hil_fw_controller_name(id), c->name) == 0, "entry %u named", id);
        CHECK(id == HIL_FW_CTRL_OFF ? c->phases == 0u : c->phases == 3u || c->phases == 6u,
              "entry %u phases %u", id, c->phases);
        CHECK(hil_fw_controller_implemented(id), "entry %u implemented", id);
    }
    CHECK(strcmp(hil_fw_controller_name(HIL_FW_CTRL_FCS_MPC_1), HIL_FW_CTRL_FCS_MPC_1_NAME) == 0, "DBC name");
    CHECK(hil_fw_controller_get(HIL_FW_CTRL_MPTC2)->phases == 6u, "mptc2 drives six phases");
    CHECK(hil_fw_controller_get(HIL_FW_CTRL_COUNT) == NULL, "no entry past the count");
    CHECK(strcmp(hil_fw_controller_name(HIL_FW_CTRL_COUNT), "?") == 0, "unknown name");
    CHECK(!hil_fw_controller_implemented(HIL_FW_CTRL_COUNT), "unknown id not implemented");
}

/* Three-phase (or six-phase) measurement with a balanced current at angle th. */
static hil_fw_meas_t meas(uint16_t seq, uint8_t n_phases, float th)
{
    hil_fw_meas_t m = fw_meas_dq(seq, 0.5f, 5.0f, th, 150.0f, 300.0f);
    m.n_phases = n_phases;
    if (n_phases == 6u) {
        m.i_abc[3] = m.i_abc[0];
        m.i_abc[4] = m.i_abc[1];
        m.i_abc[5] = m.i_abc[2];
    }
    return m;
}

static void run_steps(hil_fw_state_t *s, uint8_t n_phases, int k0, int n)
{
    int k;
    for (k = k0; k < k0 + n; ++k) {
        const hil_fw_meas_t m = meas((uint16_t)k, n_phases, 0.05f * (float)k);
        hil_fw_cmd_t c;
        hil_fw_step(s, &m, (uint64_t)k * TS_NS, &c);
    }
}

/* 1 if every byte of the controller state is zero except the DSVM family's reset marker. */
static int ctrl_is_reset(const hil_fw_state_t *s)
{
    hil_fw_state_t want;
    memset(&want.ctrl, 0, sizeof want.ctrl);
    if (hil_fw_controller_get(s->controller_id)->reset == hil_fw_dsvm_reset) {
        want.ctrl.dsvm.next_t_ns = HIL_FW_DSVM_NO_STEP;
    }
    return memcmp(&want.ctrl, &s->ctrl, sizeof s->ctrl) == 0;
}

static void test_reset_on_select_and_enable(void)
{
    uint8_t id;
    for (id = 1u; id < HIL_FW_CTRL_COUNT; ++id) {
        const uint8_t phases = hil_fw_controller_get(id)->phases;
        const uint8_t other = phases == 6u ? HIL_FW_CTRL_MPTC1 : HIL_FW_CTRL_MPCC;
        hil_fw_state_t s;
        unsigned char before[sizeof s.ctrl];
        hil_fw_init(&s);
        CHECK(hil_fw_select_controller(&s, other) == HIL_FW_OK, "select %u", other);
        CHECK(hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_TORQUE, 3.0f) == HIL_FW_OK, "enable");
        memset(&s.ctrl, 0xA5, sizeof s.ctrl); /* stale state of the previous controller */
        if (id != other) {
            CHECK(hil_fw_select_controller(&s, id) == HIL_FW_OK, "select %u", id);
            CHECK(ctrl_is_reset(&s), "controller %s: state reset on select", hil_fw_controller_name(id));
        }
        run_steps(&s, phases, 0, 20);
        memcpy(before, &s.ctrl, sizeof before);
        CHECK(hil_fw_select_controller(&s, id) == HIL_FW_OK, "select %u again", id);
        CHECK(hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_TORQUE, 4.0f) == HIL_FW_OK, "new reference");
        CHECK(memcmp(before, &s.ctrl, sizeof before) == 0,
              "controller %s: state kept when re-selected and on a new reference", hil_fw_controller_name(id));
        CHECK(hil_fw_set_setpoint(&s, 0u, HIL_FW_MODE_TORQUE, 4.0f) == HIL_FW_OK, "disable");
        CHECK(memcmp(before, &s.ctrl, sizeof before) == 0, "disable keeps the state");
        CHECK(hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_TORQUE, 4.0f) == HIL_FW_OK, "enable");
        CHECK(ctrl_is_reset(&s), "controller %s: state reset on enable", hil_fw_controller_name(id));
    }
}

/* fcs-mpc-1's flux observer restarts from the current model after a re-enable even when time runs on
 * without a gap (the reset, not a time jump, starts it); without the re-enable it keeps integrating. */
static void test_observer_restarts_on_enable(void)
{
    hil_fw_state_t toggled, running, fresh;
    const hil_fw_meas_t m = meas(40u, 3u, 2.0f);
    hil_fw_cmd_t c;
    hil_fw_init(&toggled);
    (void)hil_fw_set_param(&toggled, HIL_FW_P_FCS_READING, 0.0f);
    (void)hil_fw_select_controller(&toggled, HIL_FW_CTRL_FCS_MPC_1);
    (void)hil_fw_set_setpoint(&toggled, 1u, HIL_FW_MODE_TORQUE, 3.0f);
    fresh = toggled;
    run_steps(&toggled, 3u, 0, 40);
    running = toggled;
    (void)hil_fw_set_setpoint(&toggled, 0u, HIL_FW_MODE_TORQUE, 3.0f);
    (void)hil_fw_set_setpoint(&toggled, 1u, HIL_FW_MODE_TORQUE, 3.0f);
    hil_fw_step(&toggled, &m, 40u * TS_NS, &c);
    hil_fw_step(&running, &m, 40u * TS_NS, &c);
    hil_fw_step(&fresh, &m, 40u * TS_NS, &c);
    CHECK(toggled.ctrl.dsvm.psi_a == fresh.ctrl.dsvm.psi_a && toggled.ctrl.dsvm.psi_b == fresh.ctrl.dsvm.psi_b,
          "re-enabled observer starts from the current model as a fresh one");
    CHECK(running.ctrl.dsvm.psi_a != fresh.ctrl.dsvm.psi_a, "a running observer integrates (control)");
    CHECK(toggled.ctrl.dsvm.next_t_ns == 41u * TS_NS, "next step expected one period later");
}

static void test_phase_count_from_the_table(void)
{
    uint8_t id;
    for (id = 1u; id < HIL_FW_CTRL_COUNT; ++id) {
        const uint8_t phases = hil_fw_controller_get(id)->phases;
        hil_fw_state_t s;
        hil_fw_meas_t right = meas(1u, phases, 0.3f);
        hil_fw_meas_t wrong = meas(1u, phases == 6u ? 3u : 6u, 0.3f);
        hil_fw_cmd_t c;
        hil_fw_init(&s);
        (void)hil_fw_select_controller(&s, id);
        hil_fw_step(&s, &right, 0u, &c);
        CHECK(c.status == HIL_FW_STATUS_OK, "%s: %u phases accepted", hil_fw_controller_name(id), phases);
        hil_fw_step(&s, &wrong, TS_NS, &c);
        CHECK(c.status == HIL_FW_STATUS_INVALID_CONFIG, "%s: %u phases refused", hil_fw_controller_name(id),
              wrong.n_phases);
    }
}

int main(void)
{
    test_table_entries();
    test_reset_on_select_and_enable();
    test_observer_restarts_on_enable();
    test_phase_count_from_the_table();
    return FW_REPORT("test_controllers");
}
