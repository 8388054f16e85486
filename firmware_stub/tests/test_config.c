/* Configuration: parameter validation, controller selection, setpoint validation, defaults (incl. the
 * per-controller fcs_reading default). */
#include "fw_check.h"
#include "fw_fixture.h"
#include "hil_fw.h"
#include "hil_fw_fcs_mpc.h"

static void test_param_validation(void)
{
    hil_fw_state_t s;
    float v = 0.0f;
    hil_fw_init(&s);
    CHECK(hil_fw_set_param(&s, HIL_FW_P_LD, -0.001f) == HIL_FW_E_PARAM_VALUE, "negative Ld rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_LQ, 0.0f) == HIL_FW_E_PARAM_VALUE, "zero Lq rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_TS, 0.0f) == HIL_FW_E_PARAM_VALUE, "zero Ts rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_TS, -1e-4f) == HIL_FW_E_PARAM_VALUE, "negative Ts rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_RS, -1.0f) == HIL_FW_E_PARAM_VALUE, "negative Rs rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_VDC, 0.0f) == HIL_FW_E_PARAM_VALUE, "zero Vdc rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_POLE_PAIRS, 2.5f) == HIL_FW_E_PARAM_VALUE, "fractional p rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_POLE_PAIRS, 0.0f) == HIL_FW_E_PARAM_VALUE, "zero p rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_TORQUE_LIMIT, 0.0f) == HIL_FW_E_PARAM_VALUE, "zero limit rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_CURRENT_LIMIT, -2.0f) == HIL_FW_E_PARAM_VALUE,
          "negative current limit rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_SPEED_KP, NAN) == HIL_FW_E_PARAM_VALUE, "NaN rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_PSI_F, INFINITY) == HIL_FW_E_PARAM_VALUE, "inf rejected");
    {   /* every parameter refuses NaN and +-inf (a ConfigParam frame can carry them) */
        const float bad[3] = {NAN, INFINITY, -INFINITY};
        unsigned id;
        int b;
        for (id = 1u; id < HIL_FW_P_COUNT; ++id) {
            for (b = 0; b < 3; ++b) {
                CHECK(hil_fw_set_param(&s, (uint8_t)id, bad[b]) == HIL_FW_E_PARAM_VALUE, "param %u = %g rejected",
                      id, (double)bad[b]);
            }
        }
    }
    CHECK(hil_fw_set_param(&s, 0u, 1.0f) == HIL_FW_E_PARAM_ID, "param id 0 rejected");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_COUNT, 1.0f) == HIL_FW_E_PARAM_ID, "param id past the last rejected");
    CHECK(hil_fw_set_param(&s, 255u, 1.0f) == HIL_FW_E_PARAM_ID, "param id 255 rejected");
    CHECK(hil_fw_set_param(NULL, HIL_FW_P_RS, 1.0f) == HIL_FW_E_NULL, "null state rejected");
    /* Rejected values leave the state unchanged. */
    CHECK(hil_fw_get_param(&s, HIL_FW_P_LD, &v) == 0 && v == 0.012f, "Ld unchanged after rejection");
    CHECK(s.params.model.ts_ns == 100000u, "Ts unchanged after rejection, got %u ns", s.params.model.ts_ns);
    /* Accepted values update the derived model. */
    CHECK(hil_fw_set_param(&s, HIL_FW_P_TS, 50e-6f) == 0, "Ts 50 us accepted");
    CHECK(s.params.model.ts_ns == 50000u, "Ts 50 us -> %u ns", s.params.model.ts_ns);
    CHECK(hil_fw_set_param(&s, HIL_FW_P_LQ, 0.02f) == 0, "Lq accepted");
    CHECK_NEAR(s.params.model.kq, 50e-6f / 0.02f, 1e-9f, "Ts/Lq derived");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_ID_REF, -3.0f) == 0, "negative id_ref accepted");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_TORQUE_INTEGRATOR_INIT, -2.0f) == 0, "negative preset accepted");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_SPEED_KP, 1.2f) == 0 && s.speed_pi.kp == 1.2f, "kp reaches the PI");
}

static void test_defaults(void)
{
    hil_fw_state_t s;
    float v = 0.0f;
    hil_fw_init(&s);
    CHECK(hil_fw_get_param(&s, HIL_FW_P_SPEED_KP, &v) == 0 && v == 0.8f, "default kp 0.8 (paper)");
    CHECK(hil_fw_get_param(&s, HIL_FW_P_SPEED_KI, &v) == 0 && v == 0.35f, "default ki 0.35 (paper)");
    CHECK(hil_fw_get_param(&s, HIL_FW_P_POLE_PAIRS, &v) == 0 && v == 3.0f, "default p 3 (Table 3)");
    CHECK(hil_fw_get_param(&s, HIL_FW_P_RS, &v) == 0 && v == 4.5f, "default Rs 4.5 (Table 3)");
    CHECK(hil_fw_get_param(&s, 99u, &v) == HIL_FW_E_PARAM_ID, "get of unknown id rejected");
    CHECK(s.controller_id == HIL_FW_CTRL_OFF && s.enable == 0u, "starts off and disabled");
    CHECK(s.params.model.ts_ns == 100000u, "default Ts 100 us");
}

static void test_controller_selection(void)
{
    hil_fw_state_t s;
    uint8_t id;
    hil_fw_init(&s);
    CHECK(hil_fw_select_controller(&s, HIL_FW_CTRL_MPCC) == 0, "mpcc selectable");
    CHECK(s.controller_id == HIL_FW_CTRL_MPCC, "mpcc selected");
    CHECK(hil_fw_select_controller(&s, HIL_FW_CTRL_COUNT) == HIL_FW_E_CONTROLLER_ID, "id past the last unknown");
    CHECK(hil_fw_select_controller(&s, 200u) == HIL_FW_E_CONTROLLER_ID, "id 200 unknown");
    for (id = 2u; id < HIL_FW_CTRL_COUNT; ++id) {
        if (!hil_fw_controller_implemented(id)) {
            CHECK(hil_fw_select_controller(&s, id) == HIL_FW_E_NOT_IMPLEMENTED, "id %u not implemented", id);
        }
    }
    CHECK(s.controller_id == HIL_FW_CTRL_MPCC, "failed selections keep mpcc");
    CHECK(hil_fw_select_controller(&s, HIL_FW_CTRL_OFF) == 0, "off selectable");
    CHECK(hil_fw_controller_implemented(HIL_FW_CTRL_MPCC) == 1, "mpcc implemented");
    CHECK(hil_fw_controller_implemented(HIL_FW_CTRL_FOC) == 1, "foc implemented");
    CHECK(hil_fw_controller_name(HIL_FW_CTRL_3VMPC)[0] == '3', "name of id 10 is 3vmpc");
    CHECK(hil_fw_controller_name(77u)[0] == '?', "name of an unknown id is ?");
}

static void test_setpoint(void)
{
    hil_fw_state_t s;
    hil_fw_init(&s);
    CHECK(hil_fw_set_setpoint(&s, 1u, 2u, 1.0f) == HIL_FW_E_MODE, "mode 2 rejected");
    CHECK(hil_fw_set_setpoint(&s, 1u, 0u, NAN) == HIL_FW_E_REFERENCE, "NaN reference rejected");
    CHECK(s.enable == 0u, "rejected setpoints do not enable");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_TORQUE_INTEGRATOR_INIT, 3.0f) == 0, "preset accepted");
    CHECK(hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_SPEED, 100.0f) == 0, "speed setpoint accepted");
    CHECK_NEAR(s.speed_pi.integ, 3.0f, 0.0f, "rising enable presets the integrator");
    s.speed_pi.integ = 5.0f;
    CHECK(hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_SPEED, 120.0f) == 0, "reference change accepted");
    CHECK_NEAR(s.speed_pi.integ, 5.0f, 0.0f, "reference change while running keeps the integrator");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_TORQUE_INTEGRATOR_INIT, 50.0f) == 0, "large preset accepted");
    CHECK(hil_fw_set_setpoint(&s, 0u, HIL_FW_MODE_SPEED, 0.0f) == 0, "disable accepted");
    CHECK(hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_SPEED, 0.0f) == 0, "re-enable accepted");
    CHECK_NEAR(s.speed_pi.integ, 10.5f, 0.0f, "preset clamped to the torque limit");
}

/* fcs_reading defaults per controller: the power-on sentinel resolves to 11 for fcs-mpc-1 and 0 for
 * fcs-mpc-2 at every step, whatever the order of parameter writes and controller selection. */
#define DEG (HIL_FW_PI_F / 180.0f)

/* Configure per `order` (0: select then write, 1: write then select, 2: no write), take one torque-mode
 * step (7 N*m) with the current-model flux at 15 deg (i_q 6 A, standstill), return the command. */
static hil_fw_cmd_t step_at_15deg(hil_fw_state_t *s, uint8_t ctrl, int order, float reading)
{
    hil_fw_cmd_t cmd;
    const float delta = atan2f(0.014f * 6.0f, 0.21f); /* flux angle ahead of d at id = 0 */
    hil_fw_meas_t m = fw_meas_dq(0u, 0.0f, 6.0f, 15.0f * DEG - delta, 0.0f, 311.0f);
    hil_fw_init(s);
    if (order == 1) {
        CHECK(hil_fw_set_param(s, HIL_FW_P_FCS_READING, reading) == HIL_FW_OK, "write %g", (double)reading);
    }
    CHECK(hil_fw_select_controller(s, ctrl) == HIL_FW_OK, "select %u", (unsigned)ctrl);
    if (order == 0) {
        CHECK(hil_fw_set_param(s, HIL_FW_P_FCS_READING, reading) == HIL_FW_OK, "write %g", (double)reading);
    }
    (void)hil_fw_set_setpoint(s, 1u, HIL_FW_MODE_TORQUE, 7.0f);
    fw_set_applied(s, 0u);
    hil_fw_step(s, &m, 0u, &cmd);
    return cmd;
}

static int same_cmd(const hil_fw_cmd_t *a, const hil_fw_cmd_t *b)
{
    int i;
    if (a->n_states != b->n_states || a->vector_id != b->vector_id || a->candidates != b->candidates) {
        return 0;
    }
    for (i = 0; i < a->n_states; ++i) {
        if (a->states[i] != b->states[i] || a->durations_ns[i] != b->durations_ns[i]) {
            return 0;
        }
    }
    return 1;
}

static void test_fcs_reading_power_on(void)
{
    hil_fw_state_t s;
    float v = -1.0f;
    hil_fw_init(&s);
    CHECK(hil_fw_get_param(&s, HIL_FW_P_FCS_READING, &v) == HIL_FW_OK &&
              v == (float)HIL_FW_FCS_READING_CONTROLLER_DEFAULT,
          "power-on fcs_reading is the controller-default sentinel, got %g", (double)v);
    CHECK(hil_fw_set_param(&s, HIL_FW_P_FCS_READING, (float)HIL_FW_FCS_READING_CONTROLLER_DEFAULT) ==
              HIL_FW_E_PARAM_VALUE,
          "the sentinel is not a ConfigParam value (rotation field 15)");
}

static void test_fcs_reading_resolution(void)
{
    hil_fw_state_t s;
    hil_fw_init(&s);
    (void)hil_fw_select_controller(&s, HIL_FW_CTRL_FCS_MPC_1);
    CHECK(hil_fw_fcs_reading(&s) == 11u, "fcs-mpc-1 default 11, got %u", hil_fw_fcs_reading(&s));
    (void)hil_fw_select_controller(&s, HIL_FW_CTRL_FCS_MPC_2);
    CHECK(hil_fw_fcs_reading(&s) == 0u, "fcs-mpc-2 default 0, got %u", hil_fw_fcs_reading(&s));
    (void)hil_fw_select_controller(&s, HIL_FW_CTRL_FCS_MPC_1);
    CHECK(hil_fw_fcs_reading(&s) == 11u, "back to fcs-mpc-1: 11 again");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_FCS_READING, 0.0f) == HIL_FW_OK, "explicit 0 accepted");
    CHECK(hil_fw_fcs_reading(&s) == 0u, "explicit 0 overrides fcs-mpc-1's default");
    CHECK(hil_fw_set_param(&s, HIL_FW_P_FCS_READING, 43.0f) == HIL_FW_OK, "explicit 43 accepted");
    (void)hil_fw_select_controller(&s, HIL_FW_CTRL_FCS_MPC_2);
    CHECK(hil_fw_fcs_reading(&s) == 43u, "an explicit value survives a controller change");
}

static void test_fcs_reading_order_independent(void)
{
    static const uint8_t ctrl[2] = {HIL_FW_CTRL_FCS_MPC_1, HIL_FW_CTRL_FCS_MPC_2};
    static const float own[2] = {(float)HIL_FW_FCS_READING_DEFAULT_1, (float)HIL_FW_FCS_READING_DEFAULT_2};
    /* flux at 15 deg: S = 2 with r = 11 (S = 1 spans [-60, 0) deg), S = 1 with r = 0 */
    static const uint8_t sector[2] = {2u, 1u};
    hil_fw_state_t s;
    int c;
    int order;
    for (c = 0; c < 2; ++c) {
        const hil_fw_cmd_t dflt = step_at_15deg(&s, ctrl[c], 2, 0.0f);
        CHECK(s.ctrl.dsvm.sector == sector[c], "controller %u default: sector %u", (unsigned)ctrl[c],
              (unsigned)s.ctrl.dsvm.sector);
        for (order = 0; order < 2; ++order) {
            const hil_fw_cmd_t expl = step_at_15deg(&s, ctrl[c], order, own[c]);
            CHECK(same_cmd(&dflt, &expl), "controller %u: default = explicit %g (order %d)", (unsigned)ctrl[c],
                  (double)own[c], order);
            CHECK(s.ctrl.dsvm.sector == sector[c], "controller %u explicit: sector %u", (unsigned)ctrl[c],
                  (unsigned)s.ctrl.dsvm.sector);
        }
        /* the other controller's default written explicitly changes the sector */
        (void)step_at_15deg(&s, ctrl[c], 1, own[1 - c]);
        CHECK(s.ctrl.dsvm.sector == sector[1 - c], "controller %u with reading %g: sector %u", (unsigned)ctrl[c],
              (double)own[1 - c], (unsigned)s.ctrl.dsvm.sector);
    }
}

int main(void)
{
    test_param_validation();
    test_defaults();
    test_controller_selection();
    test_setpoint();
    test_fcs_reading_power_on();
    test_fcs_reading_resolution();
    test_fcs_reading_order_independent();
    return FW_REPORT("test_config");
}
