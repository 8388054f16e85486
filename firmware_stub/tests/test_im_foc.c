/* im-foc: the current-model rotor-flux estimator against the model's exact steady states, the flux-frame
 * references, the command shape and the reset to zero flux. Machine: im-2k2 (Rs 3.7, RR 2.1 Ohm, L_sigma 0.021,
 * L_M 0.224 H, 2 pole pairs, 540 V). */
#include <math.h>

#include "fw_check.h"
#include "fw_fixture.h"
#include "hil_fw.h"
#include "hil_fw_im_foc.h"

#define TS_NS 100000u
#define LM 0.224f
#define RR 2.1f

static void setup(hil_fw_state_t *s, float torque)
{
    static const fw_param_t machine[] = {
        {HIL_FW_P_RS, 3.7f}, {HIL_FW_P_RR, RR}, {HIL_FW_P_LSIGMA, 0.021f}, {HIL_FW_P_LM, LM},
        {HIL_FW_P_PSI_R_REF, 0.9f}, {HIL_FW_P_POLE_PAIRS, 2.0f}, {HIL_FW_P_VDC, 540.0f},
        {HIL_FW_P_CURRENT_KP, 66.0f}, {HIL_FW_P_CURRENT_KI, 18221.0f}, {HIL_FW_P_CURRENT_LIMIT, 12.0f},
        {HIL_FW_P_TORQUE_LIMIT, 22.0f},
    };
    const int refused = fw_fixture_machine(s, machine, FW_COUNT(machine), HIL_FW_CTRL_IM_FOC, torque);
    CHECK(refused == 0, "machine set-up refused at %d", refused);
}

/* One step with stator-frame current i_s = (i_d + j i_q) e^(j angle) [A] at speed omega_m [rad/s]. */
static hil_fw_cmd_t step(hil_fw_state_t *s, uint32_t k, float i_d, float i_q, float angle, float omega_m)
{
    hil_fw_cmd_t cmd;
    const hil_fw_meas_t m = fw_meas_dq((uint16_t)k, i_d, i_q, angle, omega_m, 540.0f);
    hil_fw_step(s, &m, (uint64_t)k * TS_NS, &cmd);
    return cmd;
}

static void test_flux_estimate_at_standstill(void)
{
    hil_fw_state_t s;
    uint32_t k;
    setup(&s, 0.0f);
    for (k = 0u; k < 10000u; ++k) { /* 1 s = 9.3 rotor time constants L_M / RR */
        (void)step(&s, k, 4.0f, 0.0f, 0.0f, 0.0f);
    }
    CHECK_NEAR(s.ctrl.im_foc.psi_a, LM * 4.0f, 2e-4f, "psi_R = L_M i_s at standstill");
    CHECK_NEAR(s.ctrl.im_foc.psi_b, 0.0f, 1e-6f, "no flux across the current");
}

static void test_flux_estimate_in_the_rotating_steady_state(void)
{
    /* the model's steady state at 1000 rpm: psi_R = L_M i_d along the flux, turning at
     * omega_s = omega_e + RR i_q / psi_R, with the current (i_d, i_q) in that frame (the one the references ask
     * for). The currents are held, not driven by the voltage (open loop): the current PI's integrators would wind
     * into the voltage limit, and field weakening would follow, so they are off here (current_ki 0) */
    hil_fw_state_t s;
    const float omega_m = 1000.0f * 2.0f * HIL_FW_PI_F / 60.0f;
    const float psi = 0.9f, i_d = psi / LM, i_q = 10.0f / (3.0f * psi);
    const float omega_s = 2.0f * omega_m + RR * i_q / psi;
    float angle = 0.0f, err_angle;
    uint32_t k;
    hil_fw_cmd_t cmd;
    setup(&s, 10.0f);
    CHECK(hil_fw_set_param(&s, HIL_FW_P_CURRENT_KI, 0.0f) == 0, "ki");
    for (k = 0u; k < 10000u; ++k) {
        angle = fmodf(omega_s * (float)k * 1.0e-4f, 2.0f * HIL_FW_PI_F);
        cmd = step(&s, k, i_d, i_q, angle, omega_m);
    }
    CHECK_NEAR(s.ctrl.im_foc.psi, psi, 2e-3f, "|psi_R| of the steady state");
    err_angle = atan2f(s.ctrl.im_foc.sin_f * cosf(angle) - s.ctrl.im_foc.cos_f * sinf(angle),
                       s.ctrl.im_foc.cos_f * cosf(angle) + s.ctrl.im_foc.sin_f * sinf(angle));
    CHECK(fabsf(err_angle) < 2e-3f, "flux angle error %g rad", (double)err_angle);
    /* references in the flux frame: i_d = psi_ref / L_M at the reference flux, i_q = T / (1.5 p |psi_R|) */
    CHECK_NEAR(s.ref.i_d, 0.9f / LM, 0.05f, "flux current at the reference flux");
    CHECK_NEAR(s.ref.i_q, 10.0f / (3.0f * s.ctrl.im_foc.psi), 1e-3f, "torque current");
    CHECK(cmd.status == HIL_FW_STATUS_OK && cmd.n_states >= 1u && cmd.n_states <= 3u, "a command");
}

static void test_command_shape_and_pattern(void)
{
    hil_fw_state_t s;
    uint32_t k;
    setup(&s, 5.0f);
    for (k = 0u; k < 40u; ++k) {
        const hil_fw_cmd_t cmd = step(&s, k, 1.0f, 0.5f, 0.3f * (float)k, 50.0f);
        uint32_t sum = 0u;
        uint8_t i;
        for (i = 0u; i < cmd.n_states; ++i) {
            sum += cmd.durations_ns[i];
        }
        CHECK(sum == TS_NS, "step %u: durations sum to Ts, got %u", k, sum);
        CHECK(cmd.states[cmd.n_states - 1u] == ((k & 1u) ? 0u : 7u) || cmd.n_states < 3u,
              "step %u: the half ends on its zero vector", k);
    }
}

static void test_start_from_zero_flux_and_reset_on_enable(void)
{
    hil_fw_state_t s;
    setup(&s, 10.0f);
    (void)step(&s, 0u, 0.0f, 0.0f, 0.0f, 0.0f);
    /* no flux yet: the flux current takes 0.8 of the limit, the torque current the rest */
    CHECK_NEAR(s.ref.i_d, 0.8f * 12.0f, 1e-4f, "flux current limited while the flux builds");
    CHECK_NEAR(s.ref.i_q, 0.6f * 12.0f, 1e-3f, "torque current gets the rest of the limit");
    (void)step(&s, 1u, 5.0f, 0.0f, 0.0f, 0.0f);
    CHECK(s.ctrl.im_foc.psi > 0.0f, "flux estimate builds");
    CHECK(hil_fw_set_setpoint(&s, 0u, HIL_FW_MODE_TORQUE, 10.0f) == 0, "disable");
    CHECK(hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_TORQUE, 10.0f) == 0, "enable");
    CHECK(s.ctrl.im_foc.psi == 0.0f && s.ctrl.im_foc.psi_a == 0.0f && s.ctrl.im_foc.x_d == 0.0f,
          "a rising enable starts from zero flux");
}

static void test_field_weakening_above_base_speed(void)
{
    /* 1916 rpm = 1.5x the 1277 rpm base speed of the rated 14.6 N*m at 0.9 Wb: with an ideal current loop (the
     * measured currents are the references, in the estimated flux frame) the flux reference falls until the
     * voltage demand sits on 0.95 * 540 / sqrt(3) = 296.2 V, and the torque current makes up the torque. The
     * currents are fed at the flux angle advanced by the flux's turn over the period; the current PI's integrators
     * are off (current_ki 0): an open loop's small residual errors would wind them into the voltage limit */
    hil_fw_state_t s;
    const float omega_m = 1916.0f * 2.0f * HIL_FW_PI_F / 60.0f;
    const float vlim = 0.95f * 540.0f / HIL_FW_SQRT3_F;
    float i_d = 0.0f, i_q = 0.0f;
    uint32_t k;
    setup(&s, 14.6f);
    CHECK(hil_fw_set_param(&s, HIL_FW_P_CURRENT_KI, 0.0f) == 0, "ki");
    for (k = 0u; k < 20000u; ++k) {
        const float psi = s.ctrl.im_foc.psi > 0.09f ? s.ctrl.im_foc.psi : 0.09f;
        const float turn = (2.0f * omega_m + RR * i_q / psi) * 1.0e-4f;
        (void)step(&s, k, i_d, i_q, atan2f(s.ctrl.im_foc.sin_f, s.ctrl.im_foc.cos_f) + turn, omega_m);
        i_d = s.ref.i_d;
        i_q = s.ref.i_q;
    }
    CHECK(s.ctrl.im_foc.psi_ref < 0.8f, "the flux reference is weakened, got %g Wb", (double)s.ctrl.im_foc.psi_ref);
    CHECK(s.ctrl.im_foc.psi_ref > 0.25f * 0.9f, "above its floor");
    CHECK_NEAR(s.ctrl.im_foc.psi, s.ctrl.im_foc.psi_ref, 0.01f, "the flux follows its reference");
    CHECK_NEAR(s.ctrl.im_foc.v_dem, vlim, 0.02f * vlim, "the voltage demand settles on the limit");
    CHECK_NEAR(3.0f * s.ctrl.im_foc.psi * s.ref.i_q, 14.6f, 0.05f, "the torque holds");
    CHECK(s.ctrl.im_foc.dpsi_fw <= 0.0f, "the feedback only lowers the flux");
}

int main(void)
{
    test_flux_estimate_at_standstill();
    test_flux_estimate_in_the_rotating_steady_state();
    test_command_shape_and_pattern();
    test_start_from_zero_flux_and_reset_on_enable();
    test_field_weakening_above_base_speed();
    return FW_REPORT("test_im_foc");
}
