/* Reference firmware: mptc3, the weighting-factor-free MPTC (Zhang et al. 2021): 6 V3 candidates chosen by
 * the system state (Table 1) and the flux sector (Fig. 5 as derived in docs/algorithms/mptc.md),
 * simplified model eqs. (15)-(16) with the V3 mean voltage over Ts, cost J1 = |psi - psi*| (18) or
 * J2 = |T - T*| (19) by Table 2. The model needs only the V3 volt-seconds, so v3_symmetric (G1/2 - G2 - G1/2)
 * changes the emitted command, not the prediction. */
#include <math.h>

#include "hil_fw_mptc.h"
#include "hil_fw_six.h"
#include "hil_fw_state.h"

#define TWO_PI_F 6.28318530717959f
#define V3_AMP (HIL_FW_SIX_ETA_G1 * HIL_FW_SIX_G1_AMP + HIL_FW_SIX_ETA_G2 * HIL_FW_SIX_G2_AMP)

/* Offsets of the candidates from the flux sector index: J1 keeps the vectors within +-45 degrees of the
 * flux and of its opposite (flux magnitude acts, torque barely does); J2 those within +-45 degrees of
 * +-90 degrees from the flux (torque acts, flux barely does). */
const int8_t hil_fw_mptc3_set_j1[HIL_FW_MPTC3_CANDIDATES] = {-1, 0, 1, 5, 6, 7};
const int8_t hil_fw_mptc3_set_j2[HIL_FW_MPTC3_CANDIDATES] = {2, 3, 4, 8, 9, 10};

uint8_t hil_fw_mptc3_case(float err_prev, float err_now, float band)
{
    const int dyn_prev = err_prev > band;
    const int dyn_now = err_now > band;
    if (dyn_prev) {
        return dyn_now ? HIL_FW_MPTC_DYNAMIC : HIL_FW_MPTC_DYN_TO_STEADY;
    }
    return dyn_now ? HIL_FW_MPTC_STEADY_TO_DYN : HIL_FW_MPTC_STEADY;
}

void hil_fw_mptc3_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd)
{
    const float *v = s->params.value;
    hil_fw_mptc_state_t *st = &s->ctrl.mptc;
    hil_fw_mptc_ctx_t c;
    const float ts = s->params.model.ts;
    const float band = v[HIL_FW_P_TORQUE_BAND] > 0.0f ? v[HIL_FW_P_TORQUE_BAND] : 0.02f * v[HIL_FW_P_TORQUE_LIMIT];
    const float amp = V3_AMP * s->meas.vdc * ts; /* |u1 T1 + u2 T2| [V*s] */
    const float rl = v[HIL_FW_P_RS] * ts;
    const float w = s->meas.omega_e;
    const float p3 = 3.0f * v[HIL_FW_P_POLE_PAIRS];
    const int8_t *set;
    float err_prev;
    float err_now;
    float cm;
    float sm;
    float psi_d1;
    float psi_q1;
    float ang;
    float best_cost = 0.0f;
    int sector;
    int best = 0;
    int k;
    if (!hil_fw_mptc_six_phase_ok(s, cmd)) {
        return;
    }
    hil_fw_mptc_begin(s, &c);
    /* the paper's k-1 is our k (measured), its k our k+1 (delay-compensated): its vector acts at k+1 */
    err_prev = fabsf(c.te_ref - hil_fw_mptc_torque(s, s->meas.i_d, s->meas.i_q));
    err_now = fabsf(c.te_ref - st->te1);
    st->sys_case = hil_fw_mptc3_case(err_prev, err_now, band);
    st->use_j1 = (uint8_t)(st->sys_case == HIL_FW_MPTC_DYN_TO_STEADY || st->sys_case == HIL_FW_MPTC_STEADY);
    /* flux sector at k+1: stator-frame angle of (psi_d, psi_q) */
    psi_d1 = v[HIL_FW_P_LD] * c.id1 + v[HIL_FW_P_PSI_F];
    psi_q1 = v[HIL_FW_P_LQ] * c.iq1;
    ang = atan2f(c.s2, c.c2) + atan2f(psi_q1, psi_d1);
    ang -= TWO_PI_F * floorf(ang / TWO_PI_F);
    sector = isfinite(ang) ? (int)(ang * (12.0f / TWO_PI_F)) : 0; /* NaN flux: sector 1, never a NaN cast */
    sector = sector > 11 ? 11 : sector;
    st->flux_sector = (uint8_t)(sector + 1);
    set = st->use_j1 ? hil_fw_mptc3_set_j1 : hil_fw_mptc3_set_j2;
    {
        const float hc = cosf(0.5f * c.wts);
        const float hs = sinf(0.5f * c.wts);
        cm = c.c2 * hc - c.s2 * hs; /* middle of [k+1, k+2) */
        sm = c.s2 * hc + c.c2 * hs;
    }
    for (k = 0; k < HIL_FW_MPTC3_CANDIDATES; ++k) {
        const int j = (sector + set[k] + 12) % 12;
        const float ua = amp * hil_fw_mptc_dir_c[j];
        const float ub = amp * hil_fw_mptc_dir_s[j];
        const float ud = ua * cm + ub * sm; /* u_d1 T1 + u_d2 T2 [V*s] */
        const float uq = -ua * sm + ub * cm;
        /* eq. (15): currents; eq. (16): flux (psi_d = Ld i_d + psi_f, psi_q = Lq i_q) */
        const float id2 = c.id1 + (ud - rl * c.id1 + w * v[HIL_FW_P_LQ] * c.iq1 * ts) / v[HIL_FW_P_LD];
        const float iq2 = c.iq1 +
                          (uq - rl * c.iq1 - w * v[HIL_FW_P_LD] * c.id1 * ts - w * v[HIL_FW_P_PSI_F] * ts) /
                              v[HIL_FW_P_LQ];
        const float pd2 = ud + psi_d1 - rl * c.id1 + w * psi_q1 * ts;
        const float pq2 = uq + psi_q1 - rl * c.iq1 - w * psi_d1 * ts;
        float g;
        if (st->use_j1) {
            g = fabsf(sqrtf(pd2 * pd2 + pq2 * pq2) - c.psi_ref); /* J1, eq. (18) */
        } else {
            g = fabsf(p3 * (pd2 * iq2 - pq2 * id2) - c.te_ref); /* J2, eq. (19) */
        }
        if (k == 0 || g < best_cost) {
            best_cost = g;
            best = j + 1;
            st->te2 = p3 * (pd2 * iq2 - pq2 * id2);
            st->psi2 = sqrtf(pd2 * pd2 + pq2 * pq2);
        }
    }
    st->cost = best_cost;
    hil_fw_mptc_emit(s, cmd, best, 1, HIL_FW_MPTC3_CANDIDATES);
}
