/* Reference firmware: mptc2, MPTC over the 12 virtual vectors V3 (G1 for eta_G1 Ts, then G2 of the same
 * direction for eta_G2 Ts) + zero, full dual-vector model eq. (13) (two sequential forward-Euler steps,
 * each at the rotor angle in the middle of its sub-interval), cost eq. (10). With v3_symmetric the V3 is
 * applied as G1/2 - G2 - G1/2 and the model takes the three sub-intervals in turn. docs/algorithms/mptc.md. */
#include <math.h>

#include "hil_fw_mptc.h"
#include "hil_fw_six.h"
#include "hil_fw_state.h"

/* cos/sin of the rotor angle a [rad] after the angle (c0, s0). */
static void rotate(float c0, float s0, float a, float *c, float *s)
{
    const float ca = cosf(a);
    const float sa = sinf(a);
    *c = c0 * ca - s0 * sa;
    *s = s0 * ca + c0 * sa;
}

void hil_fw_mptc2_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd)
{
    const float *v = s->params.value;
    hil_fw_mptc_state_t *st = &s->ctrl.mptc;
    hil_fw_mptc_ctx_t c;
    const float ts = s->params.model.ts;
    const int sym = hil_fw_mptc_v3_symmetric(s);
    /* Sub-intervals as applied: G1 for t1, G2 for t2 (then G1 for t1 again if symmetric). */
    const float e1 = sym ? 0.5f * HIL_FW_SIX_ETA_G1 : HIL_FW_SIX_ETA_G1;
    const float t1 = e1 * ts;
    const float t2 = HIL_FW_SIX_ETA_G2 * ts;
    float c1;
    float s1;
    float c2;
    float s2;
    float c3 = 0.0f;
    float s3 = 0.0f;
    float best_cost = 0.0f;
    int best = 0;
    int j;
    if (!hil_fw_mptc_six_phase_ok(s, cmd)) {
        return;
    }
    hil_fw_mptc_begin(s, &c);
    rotate(c.c2, c.s2, 0.5f * c.wts * e1, &c1, &s1);                            /* middle of the first G1 */
    rotate(c.c2, c.s2, c.wts * (e1 + 0.5f * HIL_FW_SIX_ETA_G2), &c2, &s2);     /* middle of G2 */
    if (sym) {
        rotate(c.c2, c.s2, c.wts * (1.0f - 0.5f * e1), &c3, &s3);               /* middle of the second G1 */
    }
    for (j = -1; j < 12; ++j) { /* -1: zero vector */
        const float m1 = j < 0 ? 0.0f : HIL_FW_SIX_G1_AMP * s->meas.vdc;
        const float m2 = j < 0 ? 0.0f : HIL_FW_SIX_G2_AMP * s->meas.vdc;
        const float dc = j < 0 ? 0.0f : hil_fw_mptc_dir_c[j];
        const float ds = j < 0 ? 0.0f : hil_fw_mptc_dir_s[j];
        float id = c.id1;
        float iq = c.iq1;
        float psi_d;
        float psi_q;
        float te;
        float psi;
        float g;
        hil_fw_mptc_euler(s, t1, m1 * (dc * c1 + ds * s1), m1 * (ds * c1 - dc * s1), &id, &iq);
        hil_fw_mptc_euler(s, t2, m2 * (dc * c2 + ds * s2), m2 * (ds * c2 - dc * s2), &id, &iq);
        if (sym) {
            hil_fw_mptc_euler(s, t1, m1 * (dc * c3 + ds * s3), m1 * (ds * c3 - dc * s3), &id, &iq);
        }
        psi_d = v[HIL_FW_P_LD] * id + v[HIL_FW_P_PSI_F];
        psi_q = v[HIL_FW_P_LQ] * iq;
        te = 3.0f * v[HIL_FW_P_POLE_PAIRS] * (psi_d * iq - psi_q * id);
        psi = sqrtf(psi_d * psi_d + psi_q * psi_q);
        g = fabsf(c.te_ref - te) + c.lambda * fabsf(c.psi_ref - psi);
        if (j < 0 || g < best_cost) {
            best_cost = g;
            best = j + 1;
            st->te2 = te;
            st->psi2 = psi;
        }
    }
    st->cost = best_cost;
    hil_fw_mptc_emit(s, cmd, best, 1, HIL_FW_MPTC_FULL_CANDIDATES);
}
