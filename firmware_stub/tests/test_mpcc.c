/* MPCC: vector choice in constructed cases, delay compensation, zero-vector choice, model accuracy,
 * closed-loop current tracking against a finely integrated dq plant. */
#include "fw_check.h"
#include "fw_fixture.h"
#include "hil_fw.h"

#define TORQUE_PER_AMP (1.5f * 3.0f * 0.21f) /* Table 3 machine with id = 0 [N*m/A] */

static hil_fw_cmd_t run_step(hil_fw_state_t *s, const hil_fw_meas_t *m)
{
    hil_fw_cmd_t cmd;
    hil_fw_step(s, m, 0u, &cmd);
    return cmd;
}

static void test_obvious_vectors(void)
{
    hil_fw_state_t s;
    hil_fw_meas_t m;
    hil_fw_cmd_t c;
    /* theta = -30 deg: +q points at 60 deg = V2 (110). */
    fw_fixture_torque(&s, 5.0f);
    m = fw_meas_dq(1u, 0.0f, 0.0f, -HIL_FW_PI_F / 6.0f, 0.0f, 300.0f);
    c = run_step(&s, &m);
    CHECK(c.vector_id == 2u && c.states[0] == 6u, "+q at 60 deg: want V2/110, got V%u/%u", c.vector_id,
          c.states[0]);
    CHECK(c.candidates == 7u, "MPCC evaluates 7 vectors, got %u", c.candidates);
    /* Negative torque: -q points at 240 deg = V5 (001). */
    fw_fixture_torque(&s, -5.0f);
    c = run_step(&s, &m);
    CHECK(c.vector_id == 5u && c.states[0] == 1u, "-q at 240 deg: want V5/001, got V%u/%u", c.vector_id,
          c.states[0]);
    /* theta = 0: +q points at 90 deg, between V2 and V3; both are equally near. */
    fw_fixture_torque(&s, 7.0f);
    m = fw_meas_dq(2u, 0.0f, 0.0f, 0.0f, 0.0f, 300.0f);
    c = run_step(&s, &m);
    CHECK(c.vector_id == 2u || c.vector_id == 3u, "+q at 90 deg: want V2 or V3, got V%u", c.vector_id);
    /* Currents already on the reference at standstill: the zero vector. */
    fw_fixture_torque(&s, 3.0f);
    m = fw_meas_dq(3u, 0.0f, 3.0f / TORQUE_PER_AMP, 1.0f, 0.0f, 300.0f);
    c = run_step(&s, &m);
    CHECK(c.vector_id == 0u || c.vector_id == 7u, "on reference: want a zero vector, got V%u", c.vector_id);
    /* Large negative d error at theta = 0: -d points at 180 deg = V4 (011). */
    fw_fixture_torque(&s, 0.0f);
    (void)hil_fw_set_param(&s, HIL_FW_P_ID_REF, -8.0f);
    m = fw_meas_dq(4u, 0.0f, 0.0f, 0.0f, 0.0f, 300.0f);
    c = run_step(&s, &m);
    CHECK(c.vector_id == 4u && c.states[0] == 3u, "-d at 180 deg: want V4/011, got V%u/%u", c.vector_id,
          c.states[0]);
}

static void test_delay_compensation(void)
{
    hil_fw_state_t s;
    hil_fw_meas_t m = fw_meas_dq(1u, 0.0f, 0.0f, -HIL_FW_PI_F / 6.0f, 0.0f, 300.0f);
    hil_fw_cmd_t c;
    const float step_iq = (100.0e-6f / 0.014f) * 200.0f; /* Ts/Lq * 2/3 Vdc along +q */
    /* Previous vector V2 (+q): i(k+1) already has one step of current; holding it needs zero. */
    fw_fixture_torque(&s, step_iq * TORQUE_PER_AMP);
    fw_set_applied(&s, 6u);
    c = run_step(&s, &m);
    CHECK_NEAR(s.ctrl.mpcc.i_q1, step_iq, 1e-4f, "i_q(k+1) under the previous V2");
    CHECK_NEAR(s.ctrl.mpcc.i_d1, 0.0f, 1e-4f, "i_d(k+1) under the previous V2");
    CHECK(c.states[0] == 7u, "after 110 the zero vector is 111 (1 transition), got %u", c.states[0]);
    /* Same measurement, previous zero vector: i(k+1) = 0 and V2 is needed now. */
    fw_fixture_torque(&s, step_iq * TORQUE_PER_AMP);
    fw_set_applied(&s, 0u);
    c = run_step(&s, &m);
    CHECK_NEAR(s.ctrl.mpcc.i_q1, 0.0f, 1e-6f, "i_q(k+1) under the previous zero vector");
    CHECK(c.vector_id == 2u, "previous zero vector: want V2, got V%u", c.vector_id);
    CHECK_NEAR(s.ctrl.mpcc.i_q2, step_iq, 1e-4f, "i_q(k+2) under V2");
    /* The command just issued becomes the applied one for the next step. */
    CHECK(s.applied.states[0] == 6u, "applied state recorded, got %u", s.applied.states[0]);
}

static void test_zero_vector_choice(void)
{
    static const uint8_t prev[8] = {0u, 1u, 2u, 3u, 4u, 5u, 6u, 7u};
    static const uint8_t want[8] = {0u, 0u, 0u, 7u, 0u, 7u, 7u, 7u};
    int k;
    for (k = 0; k < 8; ++k) {
        CHECK(hil_fw_zero_state_for(prev[k]) == want[k], "zero vector after %u: want %u, got %u", prev[k],
              want[k], hil_fw_zero_state_for(prev[k]));
    }
    CHECK(hil_fw_leg_transitions(6u, 1u) == 3u, "110 -> 001 switches 3 legs");
}

/* Continuous dq model with the stator-frame vector u_ab held over one period: 4000 midpoint (RK2)
 * steps in float, independent of the firmware's one-step forward-Euler prediction. */
static void deriv(float d, float q, float th, float we, float ua, float ub, float *dd, float *dq)
{
    const float vd = ua * cosf(th) + ub * sinf(th);
    const float vq = -ua * sinf(th) + ub * cosf(th);
    *dd = (vd - 4.5f * d + we * 0.014f * q) / 0.012f;
    *dq = (vq - 4.5f * q - we * 0.012f * d - we * 0.21f) / 0.014f;
}

static void fine_period(float *id, float *iq, float theta, float we, float ua, float ub, float ts)
{
    const int n = 4000;
    const float h = ts / (float)n;
    float d = *id;
    float q = *iq;
    int k;
    for (k = 0; k < n; ++k) {
        const float th = theta + we * h * (float)k;
        float d1, q1, d2, q2;
        deriv(d, q, th, we, ua, ub, &d1, &q1);
        deriv(d + 0.5f * h * d1, q + 0.5f * h * q1, th + 0.5f * we * h, we, ua, ub, &d2, &q2);
        d += h * d2;
        q += h * q2;
    }
    *id = d;
    *iq = q;
}

static void test_prediction_accuracy(void)
{
    hil_fw_state_t s;
    const float wm = 157.08f; /* 1500 rpm */
    const float we = 3.0f * wm;
    const float theta = 0.4f;
    float ua, ub, id = 1.0f, iq = 4.0f;
    hil_fw_meas_t m = fw_meas_dq(1u, 1.0f, 4.0f, theta, wm, 300.0f);
    fw_fixture_torque(&s, 5.0f);
    fw_set_applied(&s, 6u);
    (void)run_step(&s, &m);
    hil_fw_state_voltage_ab(6u, 300.0f, &ua, &ub);
    fine_period(&id, &iq, theta, we, ua, ub, 100e-6f);
    CHECK_NEAR(s.ctrl.mpcc.i_d1, id, 0.04f, "i_d(k+1) vs fine integration at rated speed");
    CHECK_NEAR(s.ctrl.mpcc.i_q1, iq, 0.04f, "i_q(k+1) vs fine integration at rated speed (back-EMF)");
}

static void test_closed_loop_tracking(void)
{
    hil_fw_state_t s;
    const float wm = 100.0f;
    const float we = 3.0f * wm;
    const float ts = 100e-6f;
    const float torque = 4.0f;
    float id = 0.0f, iq = 0.0f, theta = 0.0f;
    uint8_t applied = 0u;
    float sum_q = 0.0f, sum_d = 0.0f, sum_abs_err = 0.0f;
    int k, n = 0;
    fw_fixture_torque(&s, torque);
    for (k = 0; k < 3000; ++k) {
        hil_fw_meas_t m = fw_meas_dq((uint16_t)k, id, iq, theta, wm, 300.0f);
        hil_fw_cmd_t c;
        float ua, ub;
        hil_fw_step(&s, &m, (uint64_t)k * 100000u, &c);
        CHECK(c.seq == (uint16_t)k, "seq echo");
        /* Command k is applied over [k+1, k+2): during [k, k+1) the previous one acts. */
        hil_fw_state_voltage_ab(applied, 300.0f, &ua, &ub);
        fine_period(&id, &iq, theta, we, ua, ub, ts);
        applied = c.states[0];
        theta += we * ts;
        if (theta > HIL_FW_PI_F) {
            theta -= 2.0f * HIL_FW_PI_F;
        }
        if (k >= 1000) {
            sum_q += iq;
            sum_d += id;
            sum_abs_err += fabsf(iq - torque / TORQUE_PER_AMP);
            ++n;
        }
    }
    CHECK_NEAR(sum_q / (float)n, torque / TORQUE_PER_AMP, 0.3f, "mean i_q tracks the torque reference");
    CHECK_NEAR(sum_d / (float)n, 0.0f, 0.3f, "mean i_d tracks zero");
    CHECK(sum_abs_err / (float)n < 1.0f, "mean |i_q error| below 1 A, got %g", (double)(sum_abs_err / (float)n));
}

static void test_command_durations(void)
{
    static const float periods[4] = {100e-6f, 50e-6f, 33e-6f, 1e-3f};
    int k;
    for (k = 0; k < 4; ++k) {
        hil_fw_state_t s;
        hil_fw_cmd_t c;
        hil_fw_meas_t m = fw_meas_dq(9u, 0.5f, 2.0f, 1.0f, 50.0f, 300.0f);
        uint32_t want = (uint32_t)lroundf(periods[k] * 1e9f);
        fw_fixture_torque(&s, 2.0f);
        CHECK(hil_fw_set_param(&s, HIL_FW_P_TS, periods[k]) == 0, "Ts accepted");
        c = run_step(&s, &m);
        CHECK(c.n_states == 1u, "MPCC issues one state per period, got %u", c.n_states);
        CHECK(c.durations_ns[0] + c.durations_ns[1] + c.durations_ns[2] == want,
              "durations sum %u ns, want %u ns", c.durations_ns[0] + c.durations_ns[1] + c.durations_ns[2],
              want);
        CHECK(c.states[0] < 8u, "state code in range, got %u", c.states[0]);
        CHECK(hil_fw_vector_state[c.vector_id] == c.states[0], "vector_id %u matches state %u", c.vector_id,
              c.states[0]);
    }
}

int main(void)
{
    test_obvious_vectors();
    test_delay_compensation();
    test_zero_vector_choice();
    test_prediction_accuracy();
    test_closed_loop_tracking();
    test_command_durations();
    return FW_REPORT("test_mpcc");
}
