/* Speed PI: gains, discretisation, output limit, clamping anti-windup, integrator preset. */
#include "fw_check.h"
#include "hil_fw.h"

int main(void)
{
    hil_fw_speed_pi_t pi;
    float u;
    int k;
    pi.kp = 0.8f;
    pi.ki = 0.35f;
    pi.limit = 10.0f;
    hil_fw_speed_pi_reset(&pi, 0.0f);

    /* One step: kp*e + ki*e*dt. */
    u = hil_fw_speed_pi_update(&pi, 2.0f, 1e-4f);
    CHECK_NEAR(u, 0.8f * 2.0f + 0.35f * 2.0f * 1e-4f, 1e-6f, "first PI output");
    CHECK_NEAR(pi.integ, 0.35f * 2.0f * 1e-4f, 1e-9f, "integrator increment ki*e*dt");

    /* Output limited in both directions. */
    u = hil_fw_speed_pi_update(&pi, 100.0f, 1e-4f);
    CHECK_NEAR(u, 10.0f, 0.0f, "positive output limit");
    u = hil_fw_speed_pi_update(&pi, -100.0f, 1e-4f);
    CHECK_NEAR(u, -10.0f, 0.0f, "negative output limit");

    /* Anti-windup: a long saturation does not charge the integrator. */
    hil_fw_speed_pi_reset(&pi, 0.0f);
    for (k = 0; k < 100000; ++k) {
        (void)hil_fw_speed_pi_update(&pi, 50.0f, 1e-4f); /* kp*e = 40 > limit */
    }
    CHECK(pi.integ <= 10.0f, "integrator clamped to limit, got %g", (double)pi.integ);
    CHECK_NEAR(pi.integ, 0.0f, 1e-6f, "integrator frozen while P alone saturates");
    u = hil_fw_speed_pi_update(&pi, -1.0f, 1e-4f);
    CHECK(u < 0.0f, "output leaves saturation at once when the error reverses, got %g", (double)u);

    /* Integrator alone saturating (small error, long time): clamped at the limit. */
    hil_fw_speed_pi_reset(&pi, 0.0f);
    for (k = 0; k < 400000; ++k) {
        (void)hil_fw_speed_pi_update(&pi, 1.0f, 1e-4f); /* 0.35 N*m/s -> limit after ~28 s */
    }
    CHECK(pi.integ <= 10.0f + 1e-6f, "integrator never exceeds the limit, got %g", (double)pi.integ);
    CHECK(pi.integ >= 9.0f, "integrator reached the limit region, got %g", (double)pi.integ);
    CHECK_NEAR(pi.out, 10.0f, 1e-6f, "output at the limit");

    /* Preset clamps to the limit. */
    hil_fw_speed_pi_reset(&pi, 25.0f);
    CHECK_NEAR(pi.integ, 10.0f, 0.0f, "preset clamped to +limit");
    hil_fw_speed_pi_reset(&pi, -3.5f);
    CHECK_NEAR(pi.integ, -3.5f, 0.0f, "preset inside the limit kept");
    CHECK_NEAR(pi.out, -3.5f, 0.0f, "preset sets the output (bumpless start)");
    u = hil_fw_speed_pi_update(&pi, 0.0f, 1e-4f);
    CHECK_NEAR(u, -3.5f, 0.0f, "zero error keeps the preset torque");
    return FW_REPORT("test_speed_pi");
}
