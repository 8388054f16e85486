/* Shared core of the plant kernels; see dq_segment.h. */
#if defined(__linux__) && !defined(_GNU_SOURCE)
#define _GNU_SOURCE /* sincos */
#endif
#include "dq_segment.h"

#include <math.h>

#define DQ_J ((double complex)I)

/* Below this |x| the Taylor polynomials stand in for libm: truncation < 1e-21 relative, far below rounding. */
#define DQ_SMALL_ARG 0.02

void dq_sincos(double x, double *s, double *c)
{
    if (fabs(x) < DQ_SMALL_ARG) { /* the sub-interval's rotations: omega_e * tau of a few µs */
        const double x2 = x * x;
        *s = x * (1.0 - x2 * (1.0 / 6.0) * (1.0 - x2 * (1.0 / 20.0) * (1.0 - x2 * (1.0 / 42.0) *
                  (1.0 - x2 * (1.0 / 72.0) * (1.0 - x2 * (1.0 / 110.0))))));
        *c = 1.0 - x2 * 0.5 * (1.0 - x2 * (1.0 / 12.0) * (1.0 - x2 * (1.0 / 30.0) * (1.0 - x2 * (1.0 / 56.0) *
                  (1.0 - x2 * (1.0 / 90.0)))));
        return;
    }
#if defined(__GLIBC__)
    sincos(x, s, c);
#else
    *s = sin(x);
    *c = cos(x);
#endif
}

/* exp(x), by its Taylor polynomial for small |x| (the decay m * tau over a few µs). */
static double dq_exp(double x)
{
    if (fabs(x) < DQ_SMALL_ARG) {
        return 1.0 + x * (1.0 + x * 0.5 * (1.0 + x * (1.0 / 3.0) * (1.0 + x * 0.25 * (1.0 + x * 0.2 *
               (1.0 + x * (1.0 / 6.0) * (1.0 + x * (1.0 / 7.0) * (1.0 + x * 0.125)))))));
    }
    return exp(x);
}

double dq_wrap_angle(double theta)
{
    /* in [0, 4 pi) (a forward step of one sub-interval): x - 2 pi is exact there (Sterbenz), equal to fmod */
    if (theta >= 0.0 && theta < 2.0 * DQ_TWO_PI) {
        return theta < DQ_TWO_PI ? theta : theta - DQ_TWO_PI;
    }
    theta = fmod(theta, DQ_TWO_PI);
    if (theta < 0.0) {
        theta += DQ_TWO_PI;
    }
    return theta;
}

void dq_machine_init(double rs, double ld, double lq, double psi_f, dq_machine_t *mc)
{
    mc->rs_ld = rs / ld;
    mc->rs_lq = rs / lq;
    mc->lq_ld = lq / ld;
    mc->ld_lq = ld / lq;
    mc->psi_lq = psi_f / lq;
    mc->inv_ld = 1.0 / ld;
    mc->inv_lq = 1.0 / lq;
    mc->m = 0.5 * (-mc->rs_ld + -mc->rs_lq);
}

void dq_segment_setup(const dq_machine_t *mc, double omega_e, double theta0, double v_alpha, double v_beta,
                      double i_d0, double i_q0, dq_segment_t *g)
{
    const double a00 = -mc->rs_ld, a01 = omega_e * mc->lq_ld;
    const double a10 = -omega_e * mc->ld_lq, a11 = -mc->rs_lq;
    const double inv_det = 1.0 / (a00 * a11 - a01 * a10);
    const double c1 = -omega_e * mc->psi_lq; /* back-EMF input on the q axis [A/s] */
    const double vmag = sqrt(v_alpha * v_alpha + v_beta * v_beta);
    double cphi = 1.0, sphi = 0.0; /* direction of the stator voltage (atan2(0, 0) = 0 for the zero vector) */
    /* (j w I - A) z = w for the input Re(w exp(j (a0 + w t))), a0 = theta0 - phi, w = (vmag / ld, j vmag / lq):
     * z = adj(B) w / det(B), B = j w I - A, written out in real arithmetic */
    const double w0 = vmag * mc->inv_ld, w1 = vmag * mc->inv_lq; /* w = (w0, j w1) */
    const double bdet_re = a00 * a11 - omega_e * omega_e - a01 * a10, bdet_im = -omega_e * (a00 + a11);
    const double inv_b = 1.0 / (bdet_re * bdet_re + bdet_im * bdet_im);
    /* numerators: b11 w0 - b01 w1 j = (j w - a11) w0 + a01 j w1;  b00 j w1 - b10 w0 = (j w - a00) j w1 + a10 w0 */
    const double n0_re = -a11 * w0, n0_im = omega_e * w0 + a01 * w1;
    const double n1_re = -omega_e * w1 + a10 * w0, n1_im = -a00 * w1;

    if (vmag > 0.0) {
        const double inv_v = 1.0 / vmag;
        cphi = v_alpha * inv_v;
        sphi = v_beta * inv_v;
    }
    g->m = mc->m;
    g->M00 = a00 - g->m;
    g->M01 = a01;
    g->M10 = a10;
    g->M11 = a11 - g->m;
    g->delta = g->M00 * g->M00 + g->M01 * g->M10;
    /* A x0 + (0, c1) = 0 */
    g->x0_const[0] = a01 * c1 * inv_det;
    g->x0_const[1] = -a00 * c1 * inv_det;
    g->z[0] = (n0_re * bdet_re + n0_im * bdet_im) * inv_b + DQ_J * ((n0_im * bdet_re - n0_re * bdet_im) * inv_b);
    g->z[1] = (n1_re * bdet_re + n1_im * bdet_im) * inv_b + DQ_J * ((n1_im * bdet_re - n1_re * bdet_im) * inv_b);
    g->omega_e = omega_e;
    dq_sincos(theta0, &g->sin_th0, &g->cos_th0);
    g->ea_re = g->cos_th0 * cphi + g->sin_th0 * sphi;
    g->ea_im = g->sin_th0 * cphi - g->cos_th0 * sphi;
    g->h0[0] = i_d0 - (g->x0_const[0] + (creal(g->z[0]) * g->ea_re - cimag(g->z[0]) * g->ea_im));
    g->h0[1] = i_q0 - (g->x0_const[1] + (creal(g->z[1]) * g->ea_re - cimag(g->z[1]) * g->ea_im));
}

/* C(tau) = cosh(sqrt(delta) tau) and S(tau) = sinh(sqrt(delta) tau) / sqrt(delta), continued to delta <= 0
 * (cos, sin / r), so that exp(M tau) = C I + S M for M*M = delta I. */
static void dq_cs(double delta, double tau, double *c, double *s)
{
    double dt2 = delta * tau * tau;
    if (fabs(dt2) < 1e-4) {
        *c = 1.0 + dt2 / 2.0 + dt2 * dt2 / 24.0;
        *s = tau * (1.0 + dt2 / 6.0 + dt2 * dt2 / 120.0);
    } else if (delta > 0.0) {
        double r = sqrt(delta);
        *c = cosh(r * tau);
        *s = sinh(r * tau) / r;
    } else {
        double r = sqrt(-delta);
        dq_sincos(r * tau, s, c);
        *s /= r;
    }
}

/* The solution from C, S, exp(m tau) and the rotating input's phasor (e_re, e_im) = exp(j (a0 + w tau)). */
static void dq_combine(const dq_segment_t *g, double c, double s, double em, double e_re, double e_im,
                       double *i_d, double *i_q)
{
    *i_d = em * (c * g->h0[0] + s * (g->M00 * g->h0[0] + g->M01 * g->h0[1])) + g->x0_const[0] +
           (creal(g->z[0]) * e_re - cimag(g->z[0]) * e_im);
    *i_q = em * (c * g->h0[1] + s * (g->M10 * g->h0[0] + g->M11 * g->h0[1])) + g->x0_const[1] +
           (creal(g->z[1]) * e_re - cimag(g->z[1]) * e_im);
}

void dq_segment_eval(const dq_segment_t *g, double tau, double *i_d, double *i_q)
{
    double c, s, em = dq_exp(g->m * tau);
    double cw, sw;
    dq_sincos(g->omega_e * tau, &sw, &cw);
    dq_cs(g->delta, tau, &c, &s);
    dq_combine(g, c, s, em, g->ea_re * cw - g->ea_im * sw, g->ea_re * sw + g->ea_im * cw, i_d, i_q);
}

void dq_walk_start(const dq_segment_t *g, double tau0, double dt, double em_step, dq_walk_t *w)
{
    double cw, sw;
    dq_sincos(g->omega_e * tau0, &sw, &cw);
    w->em = dq_exp(g->m * tau0);
    w->em_step = em_step;
    dq_cs(g->delta, tau0, &w->c, &w->s);
    dq_cs(g->delta, dt, &w->c_step, &w->s_step);
    w->e_re = g->ea_re * cw - g->ea_im * sw;
    w->e_im = g->ea_re * sw + g->ea_im * cw;
    w->cos_th = g->cos_th0 * cw - g->sin_th0 * sw;
    w->sin_th = g->cos_th0 * sw + g->sin_th0 * cw;
    dq_sincos(g->omega_e * dt, &w->rot_im, &w->rot_re);
    w->left = DQ_WALK_REANCHOR;
}

void dq_walk_eval(const dq_segment_t *g, const dq_walk_t *w, double *i_d, double *i_q)
{
    dq_combine(g, w->c, w->s, w->em, w->e_re, w->e_im, i_d, i_q);
}

int dq_walk_next(const dq_segment_t *g, dq_walk_t *w)
{
    double c = w->c, s = w->s, er = w->e_re, ct = w->cos_th;
    if (--w->left <= 0) {
        return 0; /* the caller starts afresh from the closed form */
    }
    w->em *= w->em_step;
    w->c = c * w->c_step + g->delta * s * w->s_step;
    w->s = s * w->c_step + c * w->s_step;
    w->e_re = er * w->rot_re - w->e_im * w->rot_im;
    w->e_im = er * w->rot_im + w->e_im * w->rot_re;
    w->cos_th = ct * w->rot_re - w->sin_th * w->rot_im;
    w->sin_th = ct * w->rot_im + w->sin_th * w->rot_re;
    return 1;
}

int dq_add_event(dq_event_t *ev, int n, int cap, double t, int leg, int kind, int level)
{
    int k = n;
    if (n >= cap) {
        return n;
    }
    while (k > 0 && (ev[k - 1].t > t || (ev[k - 1].t == t && ev[k - 1].kind > kind))) {
        ev[k] = ev[k - 1];
        k--;
    }
    ev[k].t = t;
    ev[k].leg = leg;
    ev[k].kind = kind;
    ev[k].level = level;
    return n + 1;
}
