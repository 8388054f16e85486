/* Step: stage split equals the one-call step, seq echo, disabled/bad-frame commands, torque to current
 * conversion with limits, speed loop scheduling from the passed-in time, profiled step. */
#include <string.h>

#include "fw_check.h"
#include "fw_fixture.h"
#include "hil_fw.h"

static void test_stages_equal_step(void)
{
    hil_fw_state_t a, b;
    int k;
    fw_fixture_torque(&a, 3.0f);
    fw_fixture_torque(&b, 3.0f);
    for (k = 0; k < 200; ++k) {
        const float th = 0.05f * (float)k;
        hil_fw_meas_t m = fw_meas_dq((uint16_t)k, 0.3f, 2.0f + 0.01f * (float)k, th, 80.0f, 300.0f);
        hil_fw_cmd_t ca, cb;
        uint32_t split[3];
        hil_fw_step(&a, &m, (uint64_t)k * 100000u, &ca);
        hil_fw_step_profiled(&b, &m, (uint64_t)k * 100000u, &cb, split);
        CHECK(ca.states[0] == cb.states[0] && ca.vector_id == cb.vector_id, "profiled step differs at %d", k);
        CHECK(split[0] < 1000000u && split[2] < 1000000u, "stage times plausible (< 1 ms)");
    }
}

static void test_disabled_and_faults(void)
{
    hil_fw_state_t s;
    hil_fw_meas_t m;
    hil_fw_cmd_t c;
    hil_fw_init(&s);
    (void)hil_fw_select_controller(&s, HIL_FW_CTRL_MPCC);
    m = fw_meas_dq(77u, 1.0f, 1.0f, 0.3f, 10.0f, 300.0f);
    hil_fw_step(&s, &m, 0u, &c);
    CHECK(c.seq == 77u, "seq echoed, got %u", c.seq);
    CHECK(c.vector_id == 0u && c.states[0] == 0u && c.candidates == 0u, "disabled: zero vector 000");
    CHECK(c.durations_ns[0] == 100000u && c.n_states == 1u, "disabled: full period");
    CHECK(c.torque_ref == 0.0f && c.iq_ref == 0.0f, "disabled: zero references");
    /* Bad frame: NaN current. */
    (void)hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_TORQUE, 2.0f);
    m.i_abc[1] = NAN;
    hil_fw_step(&s, &m, 100000u, &c);
    CHECK(c.status == HIL_FW_STATUS_BAD_FRAME, "NaN current -> bad frame, got %u", c.status);
    CHECK(c.vector_id == 0u || c.vector_id == 7u, "bad frame -> zero vector");
    /* Six-phase frame into a three-phase controller. */
    m = fw_meas_dq(78u, 1.0f, 1.0f, 0.3f, 10.0f, 300.0f);
    m.n_phases = 6u;
    hil_fw_step(&s, &m, 200000u, &c);
    CHECK(c.status == HIL_FW_STATUS_INVALID_CONFIG, "six-phase frame -> invalid config, got %u", c.status);
    /* Recovery. */
    m.n_phases = 3u;
    hil_fw_step(&s, &m, 300000u, &c);
    CHECK(c.status == HIL_FW_STATUS_OK && c.candidates == 7u, "good frame -> MPCC again");
    /* Controller off but enabled: zero vector, ok. */
    (void)hil_fw_select_controller(&s, HIL_FW_CTRL_OFF);
    hil_fw_step(&s, &m, 400000u, &c);
    CHECK(c.status == HIL_FW_STATUS_OK && c.candidates == 0u, "off: no candidates");
    CHECK(c.vector_id == 0u || c.vector_id == 7u, "off: zero vector");
}

static void test_torque_to_current(void)
{
    hil_fw_state_t s;
    hil_fw_meas_t m = fw_meas_dq(1u, 0.0f, 0.0f, 0.0f, 0.0f, 0.0f);
    hil_fw_cmd_t c;
    fw_fixture_torque(&s, 7.0f);
    hil_fw_step(&s, &m, 0u, &c);
    CHECK_NEAR(c.iq_ref, 7.0f / (1.5f * 3.0f * 0.21f), 1e-4f, "iq = T / (1.5 p psi_f)");
    CHECK_NEAR(c.id_ref, 0.0f, 0.0f, "id_ref default 0");
    /* Reluctance term with id_ref < 0 (Ld < Lq adds torque). */
    (void)hil_fw_set_param(&s, HIL_FW_P_ID_REF, -2.0f);
    hil_fw_step(&s, &m, 100000u, &c);
    CHECK_NEAR(c.iq_ref, 7.0f / (4.5f * (0.21f + (0.012f - 0.014f) * -2.0f)), 1e-4f, "iq with reluctance");
    CHECK_NEAR(c.id_ref, -2.0f, 0.0f, "id_ref from param");
    /* Torque limit and current limit. */
    (void)hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_TORQUE, 100.0f);
    hil_fw_step(&s, &m, 200000u, &c);
    CHECK_NEAR(c.torque_ref, 10.5f, 0.0f, "torque clamped to torque_limit");
    (void)hil_fw_set_param(&s, HIL_FW_P_CURRENT_LIMIT, 5.0f);
    hil_fw_step(&s, &m, 300000u, &c);
    CHECK_NEAR(sqrtf(c.id_ref * c.id_ref + c.iq_ref * c.iq_ref), 5.0f, 1e-4f, "|i_ref| clamped to limit");
    /* Measured vdc <= 0 falls back to the param. */
    CHECK_NEAR(s.meas.vdc, 300.0f, 0.0f, "vdc from param when not measured");
}

static void test_speed_loop(void)
{
    hil_fw_state_t s;
    hil_fw_cmd_t c;
    hil_fw_meas_t m = fw_meas_dq(1u, 0.0f, 0.0f, 0.0f, 90.0f, 300.0f);
    int k;
    hil_fw_init(&s);
    (void)hil_fw_select_controller(&s, HIL_FW_CTRL_MPCC);
    (void)hil_fw_set_param(&s, HIL_FW_P_TORQUE_INTEGRATOR_INIT, 2.0f);
    (void)hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_SPEED, 100.0f);
    hil_fw_step(&s, &m, 0u, &c);
    /* error 10 rad/s: 0.8 * 10 = 8 N*m + preset 2 + ki e dt. */
    CHECK_NEAR(c.torque_ref, 8.0f + 2.0f + 0.35f * 10.0f * 100e-6f, 1e-5f, "first speed PI output");
    /* Same time stamp again: the speed loop is not due, the integrator does not move. */
    hil_fw_step(&s, &m, 0u, &c);
    CHECK_NEAR(s.speed_pi.integ, 2.0f + 0.35f * 10.0f * 100e-6f, 1e-6f, "no update at the same t_ns");
    for (k = 1; k <= 100; ++k) {
        hil_fw_step(&s, &m, (uint64_t)k * 100000u, &c);
    }
    CHECK_NEAR(s.speed_pi.integ, 2.0f + 101.0f * 0.35f * 10.0f * 100e-6f, 1e-5f, "101 updates in 101 periods");
    /* Negative error drives negative torque. */
    m.omega_m = 150.0f;
    hil_fw_step(&s, &m, 101u * 100000u, &c);
    CHECK(c.torque_ref < 0.0f, "overspeed gives negative torque, got %g", (double)c.torque_ref);
}

int main(void)
{
    test_stages_equal_step();
    test_disabled_and_faults();
    test_torque_to_current();
    test_speed_loop();
    return FW_REPORT("test_step");
}
