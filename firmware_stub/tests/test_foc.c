/* foc's reference stage: MTPA against the torque equation at constant current, and field weakening by voltage-limit
 * feedback against an ideal current loop (the measured currents are the last references). Machine: niu2020-ipmsm
 * (Rs 4.5 Ohm, Ld 12 mH, Lq 14 mH, psi_f 0.21 Wb, 3 pole pairs, 311 V). */
#include <math.h>

#include "fw_check.h"
#include "fw_fixture.h"
#include "hil_fw.h"
#include "hil_fw_foc.h"

#define TS_NS 100000u
#define LD 0.012f
#define LQ 0.014f
#define PSI_F 0.21f
#define VDC 311.0f

static void setup(hil_fw_state_t *s, float torque)
{
    static const fw_param_t machine[] = {
        {HIL_FW_P_RS, 4.5f}, {HIL_FW_P_LD, LD}, {HIL_FW_P_LQ, LQ}, {HIL_FW_P_PSI_F, PSI_F}, {HIL_FW_P_POLE_PAIRS, 3.0f},
        {HIL_FW_P_VDC, VDC}, {HIL_FW_P_CURRENT_LIMIT, 24.0f}, {HIL_FW_P_TORQUE_LIMIT, 10.0f},
    };
    const int refused = fw_fixture_machine(s, machine, FW_COUNT(machine), HIL_FW_CTRL_FOC, torque);
    CHECK(refused == 0, "machine set-up refused at %d", refused);
}

static float torque_of(float i_d, float i_q)
{
    return 4.5f * (PSI_F + (LD - LQ) * i_d) * i_q;
}

static void test_mtpa_maximises_torque_per_ampere(void)
{
    const float i_q0 = 7.0f;
    const float i_d = hil_fw_mtpa_id(LD, LQ, PSI_F, i_q0);
    const float amps = sqrtf(i_d * i_d + i_q0 * i_q0);
    const float beta = atan2f(-i_d, i_q0); /* the MTPA angle of the current vector from q towards -d */
    const float t_mtpa = torque_of(-amps * sinf(beta), amps * cosf(beta));
    CHECK(i_d < 0.0f, "an IPMSM's MTPA d current is negative, got %g", (double)i_d);
    /* the closed form against the textbook root psi_f / (2 (lq - ld)) - sqrt(...) */
    CHECK_NEAR(i_d, PSI_F / (2.0f * (LQ - LD)) - sqrtf(PSI_F * PSI_F / (4.0f * (LQ - LD) * (LQ - LD)) + i_q0 * i_q0),
               1e-3f, "MTPA d current");
    /* at constant |i|, the MTPA angle's torque beats its neighbours */
    CHECK(t_mtpa >= torque_of(-amps * sinf(beta + 0.02f), amps * cosf(beta + 0.02f)), "MTPA beats a larger angle");
    CHECK(t_mtpa >= torque_of(-amps * sinf(beta - 0.02f), amps * cosf(beta - 0.02f)), "MTPA beats a smaller angle");
    CHECK(hil_fw_mtpa_id(0.0085f, 0.0085f, 0.175f, 5.0f) == 0.0f, "an SPMSM's MTPA is id = 0");
}

/* Steps with an ideal current loop: the measured dq currents are the previous step's references. */
static void run_ideal(hil_fw_state_t *s, float rpm, uint32_t steps)
{
    const float omega_m = rpm * 2.0f * HIL_FW_PI_F / 60.0f;
    float i_d = 0.0f;
    float i_q = 0.0f;
    uint32_t k;
    for (k = 0u; k < steps; ++k) {
        hil_fw_cmd_t cmd;
        const float th = fmodf(3.0f * omega_m * (float)k * 1.0e-4f, 2.0f * HIL_FW_PI_F);
        const hil_fw_meas_t m = fw_meas_dq((uint16_t)k, i_d, i_q, th, omega_m, VDC);
        hil_fw_step(s, &m, (uint64_t)k * TS_NS, &cmd);
        i_d = s->ref.i_d;
        i_q = s->ref.i_q;
    }
}

static void test_below_base_speed_mtpa_without_weakening(void)
{
    hil_fw_state_t s;
    setup(&s, 7.0f);
    run_ideal(&s, 1000.0f, 2000u);
    CHECK(s.ctrl.foc.id_fw == 0.0f, "no field weakening at 1000 rpm, got %g A", (double)s.ctrl.foc.id_fw);
    CHECK_NEAR(s.ref.i_d, hil_fw_mtpa_id(LD, LQ, PSI_F, s.ref.i_q), 1e-4f, "the d current is MTPA's");
    CHECK_NEAR(torque_of(s.ref.i_d, s.ref.i_q), 7.0f, 1e-3f, "the references make the torque");
}

static void test_above_base_speed_the_voltage_demand_settles_on_the_limit(void)
{
    /* 2915 rpm = 1.5x the base speed of the rated 7 N*m: the back-EMF alone, 916 rad/s * 0.21 Wb = 192 V, is beyond
     * the 0.95 * 311 / sqrt(3) = 170.6 V the loop holds the demand to */
    hil_fw_state_t s;
    const float vlim = 0.95f * VDC / HIL_FW_SQRT3_F;
    setup(&s, 7.0f);
    run_ideal(&s, 2915.0f, 3000u);
    CHECK(s.ref.i_d < hil_fw_mtpa_id(LD, LQ, PSI_F, s.ref.i_q) - 1.0f, "field weakening lowers id, got %g A",
          (double)s.ref.i_d);
    CHECK(s.ref.i_d > -PSI_F / LD, "id stays above the characteristic current");
    CHECK_NEAR(s.ctrl.foc.v_dem, vlim, 0.01f * vlim, "the voltage demand settles on the limit");
    CHECK_NEAR(torque_of(s.ref.i_d, s.ref.i_q), 7.0f, 1e-3f, "the torque holds (iq from the weakened id)");
    /* a gap in time (a re-enable) starts from MTPA again */
    CHECK(hil_fw_set_setpoint(&s, 0u, HIL_FW_MODE_TORQUE, 7.0f) == 0, "disable");
    CHECK(hil_fw_set_setpoint(&s, 1u, HIL_FW_MODE_TORQUE, 7.0f) == 0, "enable");
    CHECK(s.ctrl.foc.id_fw == 0.0f, "a rising enable starts without weakening");
}

int main(void)
{
    test_mtpa_maximises_torque_per_ampere();
    test_below_base_speed_mtpa_without_weakening();
    test_above_base_speed_the_voltage_demand_settles_on_the_limit();
    return FW_REPORT("test_foc");
}
