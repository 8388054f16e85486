/* Reference firmware: shared stages of the dual three-phase MPTC controllers (docs/algorithms/mptc.md). */
#include <math.h>

#include "hil_fw_mptc.h"
#include "hil_fw_six.h"
#include "hil_fw_state.h"
#include "hil_fw_transforms.h"

const float hil_fw_mptc_dir_c[12] = {0.96592583f, 0.70710678f, 0.25881905f, -0.25881905f, -0.70710678f,
                                     -0.96592583f, -0.96592583f, -0.70710678f, -0.25881905f, 0.25881905f,
                                     0.70710678f, 0.96592583f};
const float hil_fw_mptc_dir_s[12] = {0.25881905f, 0.70710678f, 0.96592583f, 0.96592583f, 0.70710678f,
                                     0.25881905f, -0.25881905f, -0.70710678f, -0.96592583f, -0.96592583f,
                                     -0.70710678f, -0.25881905f};

float hil_fw_mptc_torque(const struct hil_fw_state *s, float i_d, float i_q)
{
    const float *v = s->params.value;
    const float psi_d = v[HIL_FW_P_LD] * i_d + v[HIL_FW_P_PSI_F];
    const float psi_q = v[HIL_FW_P_LQ] * i_q;
    return 3.0f * v[HIL_FW_P_POLE_PAIRS] * (psi_d * i_q - psi_q * i_d);
}

void hil_fw_mptc_euler(const struct hil_fw_state *s, float h, float vd, float vq, float *i_d, float *i_q)
{
    const float *v = s->params.value;
    const float w = s->meas.omega_e;
    const float id = *i_d;
    const float iq = *i_q;
    *i_d = id + h / v[HIL_FW_P_LD] * (vd - v[HIL_FW_P_RS] * id + w * v[HIL_FW_P_LQ] * iq);
    *i_q = iq + h / v[HIL_FW_P_LQ] * (vq - v[HIL_FW_P_RS] * iq - w * v[HIL_FW_P_LD] * id - w * v[HIL_FW_P_PSI_F]);
}

float hil_fw_mptc_flux_cap(float psi_ref, float vdc, float omega_e)
{
    const float w = fabsf(omega_e);
    const float v_lim = HIL_FW_MPTC_FW_MARGIN * vdc / HIL_FW_SQRT3_F;
    if (w * psi_ref > v_lim) { /* only above the speed where the reference meets the limit: below it unchanged */
        return v_lim / w;
    }
    return psi_ref;
}

void hil_fw_mptc_begin(struct hil_fw_state *s, hil_fw_mptc_ctx_t *c)
{
    const float *v = s->params.value;
    const hil_fw_measured_t *me = &s->meas;
    hil_fw_mptc_state_t *st = &s->ctrl.mptc;
    const float ts = s->params.model.ts;
    const float wts = me->omega_e * ts;
    const float ch = cosf(0.5f * wts);
    const float sh = sinf(0.5f * wts);
    const float c1 = me->cos_th * ch - me->sin_th * sh; /* middle of [k, k+1) */
    const float s1 = me->sin_th * ch + me->cos_th * sh;
    const float p3 = 3.0f * v[HIL_FW_P_POLE_PAIRS];
    float ua;
    float ub;
    float id = me->i_d;
    float iq = me->i_q;
    float psi_d;
    float psi_q;
    hil_fw_six_mean_voltage_ab(s->applied.states, s->applied.durations_ns, s->applied.n_states, me->vdc, &ua, &ub);
    hil_fw_mptc_euler(s, ts, ua * c1 + ub * s1, -ua * s1 + ub * c1, &id, &iq);
    c->id1 = id;
    c->iq1 = iq;
    c->wts = wts;
    c->c2 = me->cos_th * cosf(wts) - me->sin_th * sinf(wts); /* angle at k+1 */
    c->s2 = me->sin_th * cosf(wts) + me->cos_th * sinf(wts);
    c->te_ref = s->ref.torque;
    if (v[HIL_FW_P_FLUX_REF] > 0.0f) { /* the user's fixed reference, as given (no field weakening) */
        c->psi_ref = v[HIL_FW_P_FLUX_REF];
    } else { /* i_d = 0: |psi*| = sqrt(psi_f^2 + (Lq iq*)^2), iq* = T* / (3 p psi_f); weakened at high speed */
        const float iq_ref = v[HIL_FW_P_PSI_F] > 0.0f ? c->te_ref / (p3 * v[HIL_FW_P_PSI_F]) : 0.0f;
        const float lqi = v[HIL_FW_P_LQ] * iq_ref;
        c->psi_ref = hil_fw_mptc_flux_cap(sqrtf(v[HIL_FW_P_PSI_F] * v[HIL_FW_P_PSI_F] + lqi * lqi), me->vdc,
                                          me->omega_e);
    }
    c->lambda = v[HIL_FW_P_LAMBDA] > 0.0f ? v[HIL_FW_P_LAMBDA]
                : (v[HIL_FW_P_PSI_F] > 0.0f ? v[HIL_FW_P_TORQUE_LIMIT] / v[HIL_FW_P_PSI_F] : 0.0f);
    psi_d = v[HIL_FW_P_LD] * id + v[HIL_FW_P_PSI_F];
    psi_q = v[HIL_FW_P_LQ] * iq;
    st->i_d1 = id;
    st->i_q1 = iq;
    st->te1 = hil_fw_mptc_torque(s, id, iq);
    st->psi1 = sqrtf(psi_d * psi_d + psi_q * psi_q);
    st->psi_ref = c->psi_ref;
    st->sys_case = 0u;
    st->flux_sector = 0u;
    st->use_j1 = 0u;
}

int hil_fw_mptc_v3_symmetric(const struct hil_fw_state *s)
{
    return s->params.value[HIL_FW_P_V3_SYMMETRIC] >= 0.5f;
}

void hil_fw_mptc_emit(struct hil_fw_state *s, hil_fw_cmd_t *cmd, int best, int v3, uint8_t candidates)
{
    const uint32_t ts_ns = s->params.model.ts_ns;
    cmd->states[1] = 0u;
    cmd->states[2] = 0u;
    cmd->durations_ns[1] = 0u;
    cmd->durations_ns[2] = 0u;
    cmd->mirror = 0u;
    if (best == 0) {
        const uint8_t prev = s->applied.states[s->applied.n_states > 0u ? s->applied.n_states - 1u : 0u];
        cmd->n_states = 1u;
        cmd->states[0] = hil_fw_six_zero_for(prev);
        cmd->durations_ns[0] = ts_ns;
    } else if (!v3) {
        cmd->n_states = 1u;
        cmd->states[0] = hil_fw_six_g1[best - 1];
        cmd->durations_ns[0] = ts_ns;
    } else {
        const uint32_t t1 = (uint32_t)((float)ts_ns * HIL_FW_SIX_ETA_G1 + 0.5f);
        cmd->n_states = 2u;
        cmd->states[0] = hil_fw_six_g1[best - 1];
        cmd->states[1] = hil_fw_six_g2[best - 1];
        if (hil_fw_mptc_v3_symmetric(s)) {
            /* G1/2 - G2 - G1/2: the plant mirrors the slots; an odd G1 total gives its 1 ns to G2 */
            cmd->durations_ns[0] = t1 / 2u;
            cmd->durations_ns[1] = ts_ns - 2u * (t1 / 2u);
            cmd->mirror = 1u;
        } else {
            cmd->durations_ns[0] = t1;
            cmd->durations_ns[1] = ts_ns - t1;
        }
    }
    cmd->vector_id = (uint8_t)best;
    cmd->candidates = candidates;
    cmd->status = HIL_FW_STATUS_OK;
    s->ctrl.mptc.best = (uint8_t)best;
}

int hil_fw_mptc_six_phase_ok(struct hil_fw_state *s, hil_fw_cmd_t *cmd)
{
    if (s->meas.n_phases == 6u) {
        return 1;
    }
    hil_fw_mptc_emit(s, cmd, 0, 0, 0u);
    cmd->states[0] = 0u; /* three-phase frame: a 6-bit code would be meaningless */
    cmd->status = HIL_FW_STATUS_INVALID_CONFIG;
    return 0;
}
