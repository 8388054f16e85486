/* Reference firmware: mptc1, conventional MPTC of a dual three-phase PMSM over the 12 G1 vectors + zero,
 * forward-Euler model eq. (8) over Ts, cost eq. (10) with weighting factor. docs/algorithms/mptc.md. */
#include <math.h>

#include "hil_fw_mptc.h"
#include "hil_fw_six.h"
#include "hil_fw_state.h"

/* |T* - T| + lambda | psi* - |psi| | of dq currents at k+2; also returns T and |psi|. */
static float cost10(const struct hil_fw_state *s, const hil_fw_mptc_ctx_t *c, float id, float iq, float *te,
                    float *psi)
{
    const float *v = s->params.value;
    const float psi_d = v[HIL_FW_P_LD] * id + v[HIL_FW_P_PSI_F];
    const float psi_q = v[HIL_FW_P_LQ] * iq;
    *te = 3.0f * v[HIL_FW_P_POLE_PAIRS] * (psi_d * iq - psi_q * id);
    *psi = sqrtf(psi_d * psi_d + psi_q * psi_q);
    return fabsf(c->te_ref - *te) + c->lambda * fabsf(c->psi_ref - *psi);
}

void hil_fw_mptc1_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd)
{
    hil_fw_mptc_state_t *st = &s->ctrl.mptc;
    hil_fw_mptc_ctx_t c;
    const float ts = s->params.model.ts;
    float ch;
    float sh;
    float cm;
    float sm;
    float amp;
    float te;
    float psi;
    float best_cost;
    float id = 0.0f;
    float iq = 0.0f;
    int best = 0;
    int j;
    if (!hil_fw_mptc_six_phase_ok(s, cmd)) {
        return;
    }
    hil_fw_mptc_begin(s, &c);
    ch = cosf(0.5f * c.wts);
    sh = sinf(0.5f * c.wts);
    cm = c.c2 * ch - c.s2 * sh; /* middle of [k+1, k+2) */
    sm = c.s2 * ch + c.c2 * sh;
    amp = HIL_FW_SIX_G1_AMP * s->meas.vdc;
    id = c.id1;
    iq = c.iq1;
    hil_fw_mptc_euler(s, ts, 0.0f, 0.0f, &id, &iq);
    best_cost = cost10(s, &c, id, iq, &st->te2, &st->psi2);
    for (j = 0; j < 12; ++j) {
        const float ua = amp * hil_fw_mptc_dir_c[j];
        const float ub = amp * hil_fw_mptc_dir_s[j];
        float g;
        id = c.id1;
        iq = c.iq1;
        hil_fw_mptc_euler(s, ts, ua * cm + ub * sm, -ua * sm + ub * cm, &id, &iq);
        g = cost10(s, &c, id, iq, &te, &psi);
        if (g < best_cost) {
            best_cost = g;
            best = j + 1;
            st->te2 = te;
            st->psi2 = psi;
        }
    }
    st->cost = best_cost;
    hil_fw_mptc_emit(s, cmd, best, 0, HIL_FW_MPTC_FULL_CANDIDATES);
}
