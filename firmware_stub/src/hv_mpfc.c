/*
 * Reference firmware: hybrid-vector MPFC (003_7bbad73a6f78337e.txt, Section 3), see
 * docs/algorithms/hv_mpfc.md. Shared with 3vmpc: prepare, pair_duties, modes (t_thr = 0), emit.
 */
#include <math.h>

#include "hil_fw_hv_mpfc.h"
#include "hil_fw_inverter.h"
#include "hil_fw_state.h"
#include "hil_fw_transforms.h"

#define SECTOR_RAD (HIL_FW_PI_F / 3.0f)

uint8_t hil_fw_hv_sector(float x_alpha, float x_beta)
{
    float ang = atan2f(x_beta, x_alpha);
    int k;
    if (!isfinite(ang)) {
        return 1u; /* a NaN error vector: sector 1, never a NaN cast (undefined in C) */
    }
    if (ang < 0.0f) {
        ang += 2.0f * HIL_FW_PI_F;
    }
    k = (int)(ang / SECTOR_RAD);
    if (k < 0) {
        k = 0;
    } else if (k > 5) {
        k = 5; /* ang == 2 pi after rounding */
    }
    return (uint8_t)(k + 1);
}

void hil_fw_hv_table1(uint8_t sector, uint8_t *v1, uint8_t *v2)
{
    /* Sector s lies between u_s and u_(s+1); the first vector is the odd one (u1/u3/u5). */
    const uint8_t s = (uint8_t)(sector >= 1u && sector <= 6u ? sector : 1u);
    const uint8_t a = s;
    const uint8_t b = (uint8_t)(s % 6u + 1u);
    const uint8_t odd = (a & 1u) ? a : b;
    const uint8_t even = (a & 1u) ? b : a;
    *v1 = hil_fw_vector_state[odd];
    *v2 = hil_fw_vector_state[even];
}

void hil_fw_hv_prepare(const struct hil_fw_state *s, hil_fw_hv_problem_t *p)
{
    const float *v = s->params.value;
    const hil_fw_model_t *m = &s->params.model;
    const hil_fw_measured_t *me = &s->meas;
    const float ts = m->ts;
    const float rs = v[HIL_FW_P_RS];
    const float ld = v[HIL_FW_P_LD];
    const float lq = v[HIL_FW_P_LQ];
    const float psir = v[HIL_FW_P_PSI_F];
    const float wts = me->omega_e * ts; /* electrical angle advanced per period [rad] */
    /* cos/sin at the middle of [k, k+1): theta + wts/2, and of [k+1, k+2): theta + 3 wts/2 */
    float c1;
    float s1;
    float cm;
    float sm;
    float ua;
    float ub;
    float ud;
    float uq;
    float psid;
    float psiq;
    float psid1;
    float psiq1;
    float id1;
    float iq1;
    float m0d;
    float m0q;
    float vd;
    float vq;
    float ia;
    float ib;
    float imd;
    float imq;

    /* Eq. (6) over [k, k+1) with the applied command's mean voltage (q equation with -w psi_d,
     * the sign of eq. (3); eq. (6) as printed has +). */
    hil_fw_mid_angles(me->cos_th, me->sin_th, wts, &c1, &s1, &cm, &sm);
    hil_fw_cmd_mean_voltage_ab(s->applied.states, s->applied.durations_ns, s->applied.n_states, me->vdc,
                               &ua, &ub);
    hil_fw_park(ua, ub, c1, s1, &ud, &uq);
    psid = ld * me->i_d + psir;
    psiq = lq * me->i_q;
    psid1 = psid + ts * ud + wts * psiq - ts * rs * me->i_d;
    psiq1 = psiq + ts * uq - wts * psid - ts * rs * me->i_q;
    id1 = (psid1 - psir) / ld;
    iq1 = psiq1 / lq;

    /* M0: flux change of a zero vector over [k+1, k+2) by eq. (6); eq. (9) then reads
     * d1 Ts u1 + d2 Ts u2 = dPsi - M0, i.e. the mean voltage v = (dPsi - M0) / Ts. */
    m0d = wts * psiq1 - ts * rs * id1;
    m0q = -wts * psid1 - ts * rs * iq1;
    vd = ((psir + ld * s->ref.i_d - psid1) - m0d) / ts;
    vq = ((lq * s->ref.i_q - psiq1) - m0q) / ts;

    p->v_q = vq;
    p->cos_m = cm;
    p->sin_m = sm;
    p->vdc = me->vdc;
    p->psi_d1 = psid1;
    p->psi_q1 = psiq1;
    hil_fw_park_inv(vd, vq, cm, sm, &p->v_alpha, &p->v_beta);
    /* Stator-frame flux error vector (Fig. 2): a zero vector leaves the stator flux in place there
     * except for the resistive drop, so dPsi = Ts (v - Rs i). */
    hil_fw_park_inv(id1, iq1, cm, sm, &ia, &ib);
    p->err_alpha = ts * (p->v_alpha - rs * ia);
    p->err_beta = ts * (p->v_beta - rs * ib);
    /* Phase currents in the middle of the application period (dead-time compensation signs). */
    imd = 0.5f * (id1 + s->ref.i_d);
    imq = 0.5f * (iq1 + s->ref.i_q);
    hil_fw_park_inv(imd, imq, cm, sm, &ia, &ib);
    hil_fw_clarke_inv(ia, ib, &p->i_abc[0], &p->i_abc[1], &p->i_abc[2]);
}

void hil_fw_hv_pair_duties(const hil_fw_hv_problem_t *p, uint8_t sector, float ts, hil_fw_hv_pair_t *out)
{
    float a1;
    float b1;
    float a2;
    float b2;
    float det;
    float d1;
    float d2;
    float ea;
    float eb;
    hil_fw_hv_table1(sector, &out->v1, &out->v2);
    hil_fw_state_voltage_ab(out->v1, p->vdc, &a1, &b1);
    hil_fw_state_voltage_ab(out->v2, p->vdc, &a2, &b2);
    det = a1 * b2 - b1 * a2; /* +-(2/3 Vdc)^2 sin 60 deg, never 0 for vdc > 0 */
    if (fabsf(det) < 1.0e-12f) {
        d1 = 0.0f;
        d2 = 0.0f;
    } else {
        d1 = (p->v_alpha * b2 - p->v_beta * a2) / det;
        d2 = (a1 * p->v_beta - b1 * p->v_alpha) / det;
    }
    /* Outside the pair's cone: best single vector of the pair (projection). */
    if (d1 < 0.0f || d2 < 0.0f) {
        const float p1 = (p->v_alpha * a1 + p->v_beta * b1) / (a1 * a1 + b1 * b1);
        const float p2 = (p->v_alpha * a2 + p->v_beta * b2) / (a2 * a2 + b2 * b2);
        if (d1 < 0.0f && d2 < 0.0f) {
            d1 = 0.0f;
            d2 = 0.0f;
        } else if (d1 < 0.0f) {
            d1 = 0.0f;
            d2 = p2 > 0.0f ? p2 : 0.0f;
        } else {
            d2 = 0.0f;
            d1 = p1 > 0.0f ? p1 : 0.0f;
        }
    }
    /* Over-modulation: keep the direction, scale onto the hexagon edge. */
    if (d1 + d2 > 1.0f) {
        const float k = 1.0f / (d1 + d2);
        d1 *= k;
        d2 *= k;
    }
    ea = ts * (p->v_alpha - d1 * a1 - d2 * a2);
    eb = ts * (p->v_beta - d1 * b1 - d2 * b2);
    out->d1 = d1;
    out->d2 = d2;
    out->err2 = ea * ea + eb * eb;
}

/* q component [V] of switching code `code` at the mid angle of the problem. */
static float vector_q(const hil_fw_hv_problem_t *p, uint8_t code)
{
    float a;
    float b;
    hil_fw_state_voltage_ab(code, p->vdc, &a, &b);
    return -a * p->sin_m + b * p->cos_m;
}

static float clamp01(float x)
{
    return x < 0.0f ? 0.0f : (x > 1.0f ? 1.0f : x);
}

uint8_t hil_fw_hv_modes(const hil_fw_hv_problem_t *p, const hil_fw_hv_pair_t *pair, float t_thr, uint32_t ts_ns,
                        hil_fw_dwell_t *dwell, uint8_t *requested)
{
    const float tsf = (float)ts_ns;
    const float thr = t_thr * 1.0e9f; /* [ns] */
    const uint8_t first_long = pair->d1 >= pair->d2;
    const uint8_t v_long = first_long ? pair->v1 : pair->v2;
    const uint8_t v_short = first_long ? pair->v2 : pair->v1;
    float dl = first_long ? pair->d1 : pair->d2;
    float ds = first_long ? pair->d2 : pair->d1;
    float d0 = 1.0f - dl - ds;
    uint8_t mode;
    uint8_t mode0;
    const uint8_t ok_l = dl * tsf >= thr;
    const uint8_t ok_s = ds * tsf >= thr;
    const uint8_t ok_0 = d0 * tsf >= thr;

    if (ok_l && ok_s && ok_0) {
        mode = HIL_FW_HV_MODE_THREE;
    } else if (ok_l && ok_0) {
        mode = HIL_FW_HV_MODE_ACTIVE_ZERO;
    } else if (ok_l && ok_s) {
        mode = HIL_FW_HV_MODE_TWO_ACTIVE;
    } else if (ok_l) {
        mode = HIL_FW_HV_MODE_ACTIVE;
    } else if (ok_0) {
        mode = HIL_FW_HV_MODE_ZERO;
    } else {
        mode = d0 > dl ? HIL_FW_HV_MODE_ZERO : HIL_FW_HV_MODE_ACTIVE; /* t_thr > Ts / 3: longest */
    }
    mode0 = mode;

    if (mode == HIL_FW_HV_MODE_ACTIVE_ZERO) {
        /* Eq. (10): d1 M1q + d0 M0q = dPsi_q, d1 + d0 = 1  =>  d1 = v_q / u1q. */
        const float u1q = vector_q(p, v_long);
        if (u1q * p->v_q > 0.0f) {
            dl = clamp01(p->v_q / u1q);
        }
        ds = 0.0f;
        d0 = 1.0f - dl;
        if (dl * tsf < thr) {
            mode = HIL_FW_HV_MODE_ZERO;
        } else if (d0 * tsf < thr) {
            mode = HIL_FW_HV_MODE_ACTIVE;
        }
    } else if (mode == HIL_FW_HV_MODE_TWO_ACTIVE) {
        /* Eq. (11): d1 M1q + d2 M2q = dPsi_q, d1 + d2 = 1  =>  d1 = (v_q - u2q) / (u1q - u2q). */
        const float u1q = vector_q(p, v_long);
        const float u2q = vector_q(p, v_short);
        const float du = u1q - u2q;
        if (fabsf(du) > 1.0e-3f * p->vdc) {
            dl = clamp01((p->v_q - u2q) / du);
        } else {
            dl = dl / (dl + ds);
        }
        ds = 1.0f - dl;
        d0 = 0.0f;
        if (dl * tsf < thr || ds * tsf < thr) {
            mode = HIL_FW_HV_MODE_ACTIVE; /* the longer one of the corrected pair */
        }
    }

    dwell->v_long = v_long;
    dwell->v_short = v_short;
    dwell->t_long_ns = 0u;
    dwell->t_short_ns = 0u;
    dwell->t_zero_ns = 0u;
    switch (mode) {
    case HIL_FW_HV_MODE_THREE:
    case HIL_FW_HV_MODE_ACTIVE_ZERO:
    case HIL_FW_HV_MODE_TWO_ACTIVE: {
        uint32_t tl = (uint32_t)(dl * tsf + 0.5f);
        uint32_t tsh = (uint32_t)(ds * tsf + 0.5f);
        tl = tl > ts_ns ? ts_ns : tl;
        tsh = tsh > ts_ns - tl ? ts_ns - tl : tsh;
        if (mode == HIL_FW_HV_MODE_TWO_ACTIVE) {
            tsh = ts_ns - tl; /* no zero vector: the pair fills the period */
        }
        dwell->t_long_ns = tl;
        dwell->t_short_ns = tsh;
        dwell->t_zero_ns = ts_ns - tl - tsh;
        break;
    }
    case HIL_FW_HV_MODE_ACTIVE:
        if (mode0 == HIL_FW_HV_MODE_TWO_ACTIVE && ds > dl) {
            dwell->v_long = v_short; /* eq. (11) made the shorter vector the longer one */
            dwell->v_short = v_long;
        }
        dwell->t_long_ns = ts_ns;
        break;
    default:
        dwell->t_zero_ns = ts_ns;
        break;
    }
    *requested = mode0;
    return mode;
}

void hil_fw_hv_emit(struct hil_fw_state *s, const hil_fw_hv_problem_t *p, const hil_fw_dwell_t *dwell,
                    hil_fw_cmd_t *cmd)
{
    hil_fw_hv_state_t *st = &s->ctrl.hv;
    const float *v = s->params.value;
    const uint8_t na = s->applied.n_states; /* applied sequence is mirror-expanded */
    const uint8_t prev = s->applied.states[na > 0u ? na - 1u : 0u];
    const uint8_t zsel = v[HIL_FW_P_ZERO_SELECT] >= 0.5f ? HIL_FW_ZERO_MIN_TRANSITIONS : HIL_FW_ZERO_PAPER;
    uint8_t n;
    uint8_t i;
    /* The whole symmetric sequence in one period: its distinct states with the mirror flag. */
    hil_fw_vseq_plan(&st->seq, dwell, zsel, prev, 0u, 0u);
    n = hil_fw_vseq_pack_mirror(&st->seq, HIL_FW_MAX_SUBSTATES, cmd->states, cmd->durations_ns);
    cmd->mirror = n > 1u ? 1u : 0u;
    st->dt_moved = 0u;
    if (v[HIL_FW_P_DT_COMP] >= 0.5f && v[HIL_FW_P_T_DEAD] > 0.0f) {
        const uint32_t td = (uint32_t)(v[HIL_FW_P_T_DEAD] * 1.0e9f + 0.5f);
        st->dt_moved = hil_fw_vseq_dt_comp_mirror(cmd->states, cmd->durations_ns, n, p->i_abc, td);
    }
    for (i = n; i < HIL_FW_MAX_SUBSTATES; ++i) {
        cmd->states[i] = 0u;
        cmd->durations_ns[i] = 0u;
    }
    cmd->n_states = n;
}

void hil_fw_hv_finish(struct hil_fw_state *s, const hil_fw_hv_problem_t *p, const hil_fw_hv_pair_t *pair,
                   uint8_t sector, uint8_t mode, uint8_t requested, hil_fw_cmd_t *cmd)
{
    hil_fw_hv_state_t *st = &s->ctrl.hv;
    const float ts = s->params.model.ts;
    const uint8_t first_long = pair->d1 >= pair->d2;
    st->psi_d1 = p->psi_d1;
    st->psi_q1 = p->psi_q1;
    st->err_alpha = p->err_alpha;
    st->err_beta = p->err_beta;
    st->t_opt1 = (first_long ? pair->d1 : pair->d2) * ts;
    st->t_opt2 = (first_long ? pair->d2 : pair->d1) * ts;
    st->t_zero = ts - st->t_opt1 - st->t_opt2;
    st->sector = sector;
    st->mode = mode;
    st->requested = requested;
    cmd->vector_id = (uint8_t)(16u * mode + sector);
    cmd->status = HIL_FW_STATUS_OK;
}

void hil_fw_hv_mpfc_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd)
{
    hil_fw_hv_problem_t p;
    hil_fw_hv_pair_t pair;
    hil_fw_dwell_t dwell;
    uint8_t sector;
    uint8_t mode;
    uint8_t requested;
    hil_fw_hv_prepare(s, &p);
    sector = hil_fw_hv_sector(p.err_alpha, p.err_beta); /* Table 1: one prediction */
    hil_fw_hv_pair_duties(&p, sector, s->params.model.ts, &pair);
    mode = hil_fw_hv_modes(&p, &pair, s->params.value[HIL_FW_P_T_THR], s->params.model.ts_ns, &dwell, &requested);
    hil_fw_hv_emit(s, &p, &dwell, cmd);
    hil_fw_hv_finish(s, &p, &pair, sector, mode, requested, cmd);
    cmd->candidates = 1u;
}
