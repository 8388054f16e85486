/* Shared core of the plant kernels; see dq_segment.h. */
#include "dq_segment.h"

#include <math.h>

#define DQ_J ((double complex)I)

double dq_wrap_angle(double theta)
{
    theta = fmod(theta, DQ_TWO_PI);
    if (theta < 0.0) {
        theta += DQ_TWO_PI;
    }
    return theta;
}

void dq_segment_setup(double rs, double ld, double lq, double psi_f, double omega_e, double theta0,
                      double v_alpha, double v_beta, double i_d0, double i_q0, dq_segment_t *g)
{
    double a00 = -rs / ld, a01 = omega_e * lq / ld;
    double a10 = -omega_e * ld / lq, a11 = -rs / lq;
    double det = a00 * a11 - a01 * a10;
    double c1 = -omega_e * psi_f / lq; /* back-EMF input on the q axis [A/s] */
    double vmag = hypot(v_alpha, v_beta);
    double complex w0 = vmag / ld, w1 = DQ_J * (vmag / lq);
    double complex b00 = DQ_J * omega_e - a00, b01 = -a01, b10 = -a10, b11 = DQ_J * omega_e - a11;
    double complex bdet = b00 * b11 - b01 * b10;
    double complex e;

    g->m = 0.5 * (a00 + a11);
    g->M00 = a00 - g->m;
    g->M01 = a01;
    g->M10 = a10;
    g->M11 = a11 - g->m;
    g->delta = g->M00 * g->M00 + g->M01 * g->M10;
    /* A x0 + (0, c1) = 0 */
    g->x0_const[0] = (a01 * c1) / det;
    g->x0_const[1] = -(a00 * c1) / det;
    /* (j w I - A) z = w with the input written as Re(w exp(j (a0 + w t))) */
    g->z[0] = (b11 * w0 - b01 * w1) / bdet;
    g->z[1] = (b00 * w1 - b10 * w0) / bdet;
    g->a0 = theta0 - atan2(v_beta, v_alpha);
    g->omega_e = omega_e;
    e = cexp(DQ_J * g->a0);
    g->h0[0] = i_d0 - (g->x0_const[0] + creal(g->z[0] * e));
    g->h0[1] = i_q0 - (g->x0_const[1] + creal(g->z[1] * e));
}

void dq_segment_eval(const dq_segment_t *g, double tau, double *i_d, double *i_q)
{
    double c, s, em = exp(g->m * tau);
    double dt2 = g->delta * tau * tau;
    double complex e = cexp(DQ_J * (g->a0 + g->omega_e * tau));
    if (fabs(dt2) < 1e-4) {
        c = 1.0 + dt2 / 2.0 + dt2 * dt2 / 24.0;
        s = tau * (1.0 + dt2 / 6.0 + dt2 * dt2 / 120.0);
    } else if (g->delta > 0.0) {
        double r = sqrt(g->delta);
        c = cosh(r * tau);
        s = sinh(r * tau) / r;
    } else {
        double r = sqrt(-g->delta);
        c = cos(r * tau);
        s = sin(r * tau) / r;
    }
    *i_d = em * (c * g->h0[0] + s * (g->M00 * g->h0[0] + g->M01 * g->h0[1])) + g->x0_const[0] +
           creal(g->z[0] * e);
    *i_q = em * (c * g->h0[1] + s * (g->M10 * g->h0[0] + g->M11 * g->h0[1])) + g->x0_const[1] +
           creal(g->z[1] * e);
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
