/* Field-oriented control math (foc_math.h). */
#include "foc_math.h"

#include <math.h>

float foc_wrap_2pi(float x)
{
    x = fmodf(x, FOC_TWO_PI);
    return x < 0.0f ? x + FOC_TWO_PI : x;
}

float foc_wrap_pi(float x)
{
    x = foc_wrap_2pi(x + FOC_PI) - FOC_PI;
    return x;
}

void foc_clarke(float ia, float ib, float *alpha, float *beta)
{
    /* amplitude-invariant, balanced currents (ic = -ia - ib) */
    *alpha = ia;
    *beta = (ia + 2.0f * ib) / FOC_SQRT3;
}

void foc_park(float alpha, float beta, float s, float c, float *d, float *q)
{
    *d = alpha * c + beta * s;
    *q = -alpha * s + beta * c;
}

void foc_inv_park(float d, float q, float s, float c, float *alpha, float *beta)
{
    *alpha = d * c - q * s;
    *beta = d * s + q * c;
}

float foc_pi_step(foc_pi_t *pi, float error, float ts)
{
    const float next = pi->integ + pi->ki * error * ts;
    const float out = pi->kp * error + next;
    if (out > pi->limit) {
        if (error < 0.0f) {
            pi->integ = next; /* integrate only out of the limit */
        }
        return pi->limit;
    }
    if (out < -pi->limit) {
        if (error > 0.0f) {
            pi->integ = next;
        }
        return -pi->limit;
    }
    pi->integ = next;
    return out;
}

int foc_svpwm(float v_alpha, float v_beta, float vdc, float duty[3])
{
    const float mag = sqrtf(v_alpha * v_alpha + v_beta * v_beta);
    const float vmax = vdc / FOC_SQRT3;
    const int scaled = mag > vmax;
    const float k = scaled ? vmax / mag : 1.0f;
    const float va = k * v_alpha;
    const float vb = k * (-0.5f * v_alpha + 0.5f * FOC_SQRT3 * v_beta);
    const float vc = k * (-0.5f * v_alpha - 0.5f * FOC_SQRT3 * v_beta);
    const float hi = fmaxf(va, fmaxf(vb, vc));
    const float lo = fminf(va, fminf(vb, vc));
    const float mid = 0.5f * (hi + lo);
    const float v[3] = {va, vb, vc};
    int j;
    for (j = 0; j < 3; ++j) {
        const float d = 0.5f + (v[j] - mid) / vdc;
        duty[j] = d < 0.0f ? 0.0f : (d > 1.0f ? 1.0f : d); /* rounding at the hexagon's edge */
    }
    return scaled;
}

void foc_pll_init(foc_pll_t *pll, float bandwidth_rad_s, float theta)
{
    pll->kp = 2.0f * bandwidth_rad_s; /* critically damped: s^2 + 2 wn s + wn^2 */
    pll->ki = bandwidth_rad_s * bandwidth_rad_s;
    pll->theta = foc_wrap_2pi(theta);
    pll->omega = 0.0f;
    pll->integ = 0.0f;
}

float foc_pll_step(foc_pll_t *pll, float theta_meas, float ts)
{
    const float e = foc_wrap_pi(theta_meas - pll->theta);
    pll->integ += pll->ki * e * ts;
    pll->theta = foc_wrap_2pi(pll->theta + (pll->integ + pll->kp * e) * ts);
    /* the speed is the integrator: the proportional path carries the encoder's quantisation steps */
    pll->omega = pll->integ;
    return pll->omega;
}

void foc_params_set_bandwidth(foc_params_t *p, float wc)
{
    p->kp_d = wc * p->ld;
    p->kp_q = wc * p->lq;
    p->ki_d = wc * p->rs;
    p->ki_q = wc * p->rs;
}

void foc_reset(foc_state_t *st, float vlimit)
{
    st->id_pi.integ = 0.0f;
    st->iq_pi.integ = 0.0f;
    st->id_pi.limit = vlimit;
    st->iq_pi.limit = vlimit;
    st->id = 0.0f;
    st->iq = 0.0f;
    st->vd = 0.0f;
    st->vq = 0.0f;
    st->saturated = 0u;
}

void foc_current_step(foc_state_t *st, const foc_params_t *p, float ia, float ib, float theta_e, float omega_e,
                      float vdc, float id_ref, float iq_ref, float duty[3])
{
    const float vlim = vdc / FOC_SQRT3;
    float alpha;
    float beta;
    float s = sinf(theta_e);
    float c = cosf(theta_e);
    float th;
    foc_clarke(ia, ib, &alpha, &beta);
    foc_park(alpha, beta, s, c, &st->id, &st->iq);
    st->id_pi.kp = p->kp_d;
    st->iq_pi.kp = p->kp_q;
    st->iq_pi.ki = p->ki_q;
    st->id_pi.ki = p->ki_d;
    st->id_pi.limit = vlim;
    st->iq_pi.limit = vlim;
    const float integ_d = st->id_pi.integ;
    const float integ_q = st->iq_pi.integ;
    float vq_max;
    /* PI plus decoupling feed-forward of the cross-coupling and the back EMF */
    st->vd = foc_pi_step(&st->id_pi, id_ref - st->id, p->ts) - omega_e * p->lq * st->iq;
    st->vq = foc_pi_step(&st->iq_pi, iq_ref - st->iq, p->ts) + omega_e * (p->ld * st->id + p->psi_f);
    /* the voltage vector limited to the linear range, d axis first; while limited the integrators hold (they
     * would wind up on a voltage the inverter does not give) */
    st->saturated = 0u;
    if (st->vd > vlim || st->vd < -vlim) {
        st->vd = st->vd > 0.0f ? vlim : -vlim;
        st->saturated = 1u;
    }
    vq_max = sqrtf(vlim * vlim - st->vd * st->vd);
    if (st->vq > vq_max || st->vq < -vq_max) {
        st->vq = st->vq > 0.0f ? vq_max : -vq_max;
        st->saturated = 1u;
    }
    if (st->saturated) {
        st->id_pi.integ = integ_d;
        st->iq_pi.integ = integ_q;
    }
    /* the voltage acts delay_periods later on average: rotate it there */
    th = theta_e + p->delay_periods * omega_e * p->ts;
    s = sinf(th);
    c = cosf(th);
    foc_inv_park(st->vd, st->vq, s, c, &alpha, &beta);
    (void)foc_svpwm(alpha, beta, vdc, duty); /* inside the circle: not scaled again but for rounding */
}
