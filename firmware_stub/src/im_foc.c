/* Reference firmware: im-foc, rotor-flux-oriented control of an induction machine; see hil_fw_im_foc.h. */
#include <math.h>

#include "hil_fw_foc.h"
#include "hil_fw_im_foc.h"
#include "hil_fw_inverter.h"
#include "hil_fw_state.h"
#include "hil_fw_transforms.h"

/* Below this fraction of the flux reference the flux angle is not used to divide by (build-up from zero). */
#define IM_FOC_PSI_FLOOR 0.1f
/* Time constant of the rotor-flux magnitude loop [s] (the open loop's is the rotor time constant L_M / RR, 107 ms
 * for im-2k2), and the share of the current limit the flux current may take while the flux builds up (the rest,
 * sqrt(1 - 0.8^2) = 0.6, is left to the torque current). */
#define IM_FOC_FLUX_TAU_S 0.02f
#define IM_FOC_ID_SHARE 0.8f
/* Field weakening (docs/algorithms/field_weakening.md): the share of the linear SVPWM reach vdc / sqrt(3) the
 * voltage demand is held to, the crossover of the voltage-feedback loop [rad/s] (below the flux loop's
 * 1 / IM_FOC_FLUX_TAU_S = 50 rad/s), the electrical speed below which its gain is not raised further [rad/s] and
 * the lowest flux reference as a share of psi_r_ref. */
#define IM_FOC_FW_MARGIN 0.95f
#define IM_FOC_FW_CROSSOVER 15.0f
#define IM_FOC_FW_OMEGA_FLOOR 50.0f
#define IM_FOC_FW_PSI_MIN 0.25f
/* The share of the flux reference the estimate must have reached before the feedback lowers the reference. */
#define IM_FOC_FW_BUILT 0.9f

static float clampf(float x, float lim)
{
    return x > lim ? lim : (x < -lim ? -lim : x);
}

/* psi_R(k) = e^(lambda Ts) psi_R(k-1) + (e^(lambda Ts) - 1) / lambda * RR * (i(k-1) + i(k)) / 2,
 * lambda = -RR / L_M + j omega_e: exact for a current held at the mean of its two samples over the period. */
static void update_flux(hil_fw_im_foc_state_t *st, const float *p, float ts, float omega_e, float i_a, float i_b)
{
    const float rr = p[HIL_FW_P_RR];
    const float sigma = rr / p[HIL_FW_P_LM];               /* [1/s] */
    const float decay = expf(-sigma * ts);
    const float er = decay * cosf(omega_e * ts);          /* e^(lambda Ts) */
    const float ei = decay * sinf(omega_e * ts);
    const float den = sigma * sigma + omega_e * omega_e;  /* |lambda|^2 */
    /* g = (e^(lambda Ts) - 1) / lambda = (e - 1) conj(lambda) / |lambda|^2, conj(lambda) = (-sigma, -omega_e) */
    const float gr = ((er - 1.0f) * -sigma + ei * omega_e) / den;
    const float gi = (ei * -sigma - (er - 1.0f) * omega_e) / den;
    const float ua = 0.5f * rr * (st->i_a_prev + i_a);
    const float ub = 0.5f * rr * (st->i_b_prev + i_b);
    const float pa = er * st->psi_a - ei * st->psi_b + gr * ua - gi * ub;
    const float pb = ei * st->psi_a + er * st->psi_b + gi * ua + gr * ub;
    st->psi_a = pa;
    st->psi_b = pb;
    st->i_a_prev = i_a;
    st->i_b_prev = i_b;
    st->psi = sqrtf(pa * pa + pb * pb);
    if (st->psi > 0.0f) {
        st->cos_f = pa / st->psi;
        st->sin_f = pb / st->psi;
    } else { /* zero flux: build it along alpha */
        st->cos_f = 1.0f;
        st->sin_f = 0.0f;
    }
}

void hil_fw_im_foc_reference(struct hil_fw_state *s)
{
    hil_fw_im_foc_state_t *st = &s->ctrl.im_foc;
    const hil_fw_measured_t *me = &s->meas;
    const float *p = s->params.value;
    const float imax = p[HIL_FW_P_CURRENT_LIMIT];
    const float psi_nom = p[HIL_FW_P_PSI_R_REF];
    const float psi_div = st->psi > IM_FOC_PSI_FLOOR * psi_nom ? st->psi : IM_FOC_PSI_FLOOR * psi_nom;
    const float w_abs = fabsf(me->omega_e);
    const float w_fw = w_abs > IM_FOC_FW_OMEGA_FLOOR ? w_abs : IM_FOC_FW_OMEGA_FLOOR;
    const float vlim = IM_FOC_FW_MARGIN * me->vdc / HIL_FW_SQRT3_F;
    /* d|u|/d psi_R ~ omega_e (1 + L_sigma / L_M) at the no-load steady state u_q = omega_s (L_sigma i_d + psi_R) */
    const float dudpsi = w_fw * (1.0f + p[HIL_FW_P_LSIGMA] / p[HIL_FW_P_LM]);
    const float psi_ff = vlim / dudpsi; /* the no-load flux the voltage allows (1 / omega feed-forward) */
    float psi_ref;
    float i_d;
    if (st->next_t_ns != me->t_ns) { /* a gap in time: restart the pattern, the current integrators, the weakening */
        st->parity = 0u;
        st->x_d = 0.0f;
        st->x_q = 0.0f;
        st->dpsi_fw = 0.0f;
        st->v_dem = 0.0f;
    }
    update_flux(st, p, s->params.model.ts, me->omega_e, me->i_alpha, me->i_beta);
    /* field weakening: psi_ref = min(psi_r_ref, psi_ff) + dpsi_fw, the voltage-limit feedback
     * d(dpsi_fw)/dt = (IM_FOC_FW_CROSSOVER / dudpsi) (vlim - |u|) holding dpsi_fw <= 0 and psi_ref above
     * IM_FOC_FW_PSI_MIN psi_r_ref; lowered only once the flux is built */
    psi_ref = psi_ff < psi_nom ? psi_ff : psi_nom;
    if (st->v_dem < vlim || st->psi >= IM_FOC_FW_BUILT * (psi_ref + st->dpsi_fw)) {
        /* no weakening while the flux builds: the voltage demand then comes from the build-up current */
        st->dpsi_fw += IM_FOC_FW_CROSSOVER / dudpsi * s->params.model.ts * (vlim - st->v_dem);
    }
    if (st->dpsi_fw > 0.0f) {
        st->dpsi_fw = 0.0f;
    }
    if (psi_ref + st->dpsi_fw < IM_FOC_FW_PSI_MIN * psi_nom) {
        st->dpsi_fw = IM_FOC_FW_PSI_MIN * psi_nom - psi_ref < 0.0f ? IM_FOC_FW_PSI_MIN * psi_nom - psi_ref : 0.0f;
    }
    psi_ref += st->dpsi_fw;
    st->psi_ref = psi_ref;
    /* flux P control on the current model: d|psi_R|/dt = RR i_d - RR |psi_R| / L_M = (psi_ref - |psi_R|) / tau,
     * the flux current limited to IM_FOC_ID_SHARE of the current limit while it builds */
    i_d = st->psi / p[HIL_FW_P_LM] + (psi_ref - st->psi) / (p[HIL_FW_P_RR] * IM_FOC_FLUX_TAU_S);
    i_d = clampf(i_d, IM_FOC_ID_SHARE * imax);
    s->ref.i_d = i_d;
    s->ref.i_q = psi_div > 0.0f ? clampf(s->ref.torque / (s->params.model.torque_k * psi_div),
                                         sqrtf(imax * imax - i_d * i_d))
                                : 0.0f;
}

void hil_fw_im_foc_predict(struct hil_fw_state *s, hil_fw_cmd_t *cmd)
{
    hil_fw_im_foc_state_t *st = &s->ctrl.im_foc;
    const hil_fw_measured_t *me = &s->meas;
    const float *p = s->params.value;
    const float ts = s->params.model.ts;
    const float kp = p[HIL_FW_P_CURRENT_KP];
    const float ki = p[HIL_FW_P_CURRENT_KI];
    const float ls = p[HIL_FW_P_LSIGMA];
    const float rr = p[HIL_FW_P_RR];
    const float we = me->omega_e;
    const float vmax = me->vdc / HIL_FW_SQRT3_F; /* linear range of SVPWM */
    float i_d;
    float i_q;
    float ws;
    float vd;
    float vq;
    float mag;
    float th;
    float c;
    float sn;
    float ua;
    float ub;
    hil_fw_park(me->i_alpha, me->i_beta, st->cos_f, st->sin_f, &i_d, &i_q);
    ws = st->psi > IM_FOC_PSI_FLOOR * p[HIL_FW_P_PSI_R_REF] ? we + rr * i_q / st->psi : we;
    st->next_t_ns = me->t_ns + s->params.model.ts_ns;
    vd = kp * (s->ref.i_d - i_d) + st->x_d - ws * ls * i_q - rr / p[HIL_FW_P_LM] * st->psi;
    vq = kp * (s->ref.i_q - i_q) + st->x_q + ws * ls * i_d + we * st->psi;
    mag = sqrtf(vd * vd + vq * vq);
    st->v_dem = mag; /* the field-weakening feedback: the whole demand, as foc's */
    if (mag > vmax) {
        const float k = vmax / mag;
        vd *= k;
        vq *= k;
    } else {
        st->x_d += ki * ts * (s->ref.i_d - i_d); /* conditional integration: no wind-up in saturation */
        st->x_q += ki * ts * (s->ref.i_q - i_q);
    }
    st->v_d = vd;
    st->v_q = vq;
    th = 1.5f * ws * ts; /* the flux frame in the middle of [k+1, k+2) */
    c = cosf(th);
    sn = sinf(th);
    hil_fw_park_inv(vd, vq, st->cos_f * c - st->sin_f * sn, st->sin_f * c + st->cos_f * sn, &ua, &ub);
    st->sector = hil_fw_foc_modulate(ua, ub, me->vdc, s->params.model.ts_ns, &st->parity, cmd);
}
