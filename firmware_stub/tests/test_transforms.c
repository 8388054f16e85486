/* Clarke/Park transforms: round trips and a balanced set mapping to constant dq. */
#include "fw_check.h"
#include "hil_fw.h"

int main(void)
{
    int k;
    for (k = 0; k < 72; ++k) {
        const float th = -7.0f + 0.2f * (float)k;
        const float c = cosf(th);
        const float s = sinf(th);
        const float id = 3.0f - 0.1f * (float)k;
        const float iq = -2.0f + 0.15f * (float)k;
        float al, be, a, b, cc, al2, be2, d2, q2;
        hil_fw_park_inv(id, iq, c, s, &al, &be);
        hil_fw_clarke_inv(al, be, &a, &b, &cc);
        CHECK_NEAR(a + b + cc, 0.0f, 1e-5f, "balanced abc sum");
        hil_fw_clarke(a, b, cc, &al2, &be2);
        hil_fw_park(al2, be2, c, s, &d2, &q2);
        CHECK_NEAR(d2, id, 1e-5f, "round trip d");
        CHECK_NEAR(q2, iq, 1e-5f, "round trip q");
    }
    /* Amplitude invariance: ia = I cos(th) etc. with id = 0, iq = I when theta_e = th - pi/2. */
    {
        const float amp = 5.0f;
        const float th = 0.7f;
        const float two_pi_3 = 2.0f * HIL_FW_PI_F / 3.0f;
        float al, be, d, q;
        hil_fw_clarke(amp * cosf(th), amp * cosf(th - two_pi_3), amp * cosf(th + two_pi_3), &al, &be);
        CHECK_NEAR(sqrtf(al * al + be * be), amp, 1e-5f, "alpha/beta magnitude = phase amplitude");
        hil_fw_park(al, be, cosf(th - 0.5f * HIL_FW_PI_F), sinf(th - 0.5f * HIL_FW_PI_F), &d, &q);
        CHECK_NEAR(d, 0.0f, 1e-5f, "d of a q-aligned vector");
        CHECK_NEAR(q, amp, 1e-5f, "q of a q-aligned vector");
    }
    /* Zero-sequence rejection: a common offset does not change alpha/beta. */
    {
        float al1, be1, al2, be2;
        hil_fw_clarke(1.0f, -0.4f, -0.6f, &al1, &be1);
        hil_fw_clarke(1.5f, 0.1f, -0.1f, &al2, &be2);
        CHECK_NEAR(al1, al2, 1e-6f, "alpha ignores zero sequence");
        CHECK_NEAR(be1, be2, 1e-6f, "beta ignores zero sequence");
    }
    return FW_REPORT("test_transforms");
}
