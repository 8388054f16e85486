/* Saturated PMSM from a flux map + two-level inverter; see fluxmap.h. */
#include "fluxmap.h"
#include "dq_segment.h"
#include "gate_edges.h"

#include <math.h>
#include <stddef.h>

#define FM_SQRT3 1.7320508075688772935274463415059
#define FM_MAX_EVENTS 64
#define FM_NEWTON_MAX 60
#define FM_H_MIN 1e-15
/* longest step while trace rows are written: the rows come from each step's cubic Hermite interpolant, whose error
 * grows as h^4 (about 7e-8 A at 50 us steps of an R/L = 375 1/s transient, 1e-10 A at 10 us) */
#define FM_TRACE_H_MAX 1e-5

/* Index of the cell [axis[k], axis[k+1]] holding x (x already clamped to the axis range). */
static int32_t cell_of(const double *axis, int32_t n, double x)
{
    int32_t lo = 0, hi = n - 1;
    while (hi - lo > 1) {
        const int32_t mid = (lo + hi) / 2;
        if (x >= axis[mid]) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    return lo;
}

/* Bicubic value, derivatives and mixed derivative in the cell's unit coordinates (u, v). */
static void bicubic(const double *a, double u, double v, double *f, double *fu, double *fv, double *fuv)
{
    double c[4], dc[4];
    for (int m = 0; m < 4; m++) {
        const double *r = a + 4 * m;
        c[m] = ((r[3] * v + r[2]) * v + r[1]) * v + r[0];
        dc[m] = (3.0 * r[3] * v + 2.0 * r[2]) * v + r[1];
    }
    *f = ((c[3] * u + c[2]) * u + c[1]) * u + c[0];
    *fu = (3.0 * c[3] * u + 2.0 * c[2]) * u + c[1];
    *fv = ((dc[3] * u + dc[2]) * u + dc[1]) * u + dc[0];
    *fuv = (3.0 * dc[3] * u + 2.0 * dc[2]) * u + dc[1];
}

void fm_flux(const fm_params_t *p, double i_d, double i_q, double *psi_d, double *psi_q, double *l)
{
    const double x0 = p->id_axis[0], x1 = p->id_axis[p->nx - 1];
    const double y0 = p->iq_axis[0], y1 = p->iq_axis[p->ny - 1];
    const double xc = i_d < x0 ? x0 : (i_d > x1 ? x1 : i_d);
    const double yc = i_q < y0 ? y0 : (i_q > y1 ? y1 : i_q);
    const int32_t ix = cell_of(p->id_axis, p->nx, xc);
    const int32_t iy = cell_of(p->iq_axis, p->ny, yc);
    const double hx = p->id_axis[ix + 1] - p->id_axis[ix];
    const double hy = p->iq_axis[iy + 1] - p->iq_axis[iy];
    const double u = (xc - p->id_axis[ix]) / hx;
    const double v = (yc - p->iq_axis[iy]) / hy;
    const double dx = i_d - xc, dy = i_q - yc; /* beyond the grid (at most one is nonzero per clamped side) */
    const ptrdiff_t cell = ((ptrdiff_t)ix * (p->ny - 1) + iy) * FM_COEFS;
    double fd, fdu, fdv, fduv, fq, fqu, fqv, fquv;
    bicubic(p->coef_d + cell, u, v, &fd, &fdu, &fdv, &fduv);
    bicubic(p->coef_q + cell, u, v, &fq, &fqu, &fqv, &fquv);
    fdu /= hx;
    fdv /= hy;
    fqu /= hx;
    fqv /= hy;
    fduv /= hx * hy;
    fquv /= hx * hy;
    /* outside the grid: first-order continuation from the nearest grid point, psi(pc) + grad psi(pc) . (i - pc) */
    *psi_d = fd + fdu * dx + fdv * dy;
    *psi_q = fq + fqu * dx + fqv * dy;
    if (l != NULL) {
        /* its exact Jacobian: along a clamped axis the gradient at pc; along a free axis also the change of the
         * other component's slope, d/dy (fx(pc) dx) = fxy(pc) dx (Newton stays quadratic beyond the grid) */
        const int free_x = dx == 0.0, free_y = dy == 0.0;
        l[0] = fdu + (free_x ? fduv * dy : 0.0);
        l[1] = fdv + (free_y ? fduv * dx : 0.0);
        l[2] = fqu + (free_x ? fquv * dy : 0.0);
        l[3] = fqv + (free_y ? fquv * dx : 0.0);
    }
}

int fm_currents(const fm_params_t *p, double psi_d, double psi_q, double *i_d, double *i_q)
{
    double x = *i_d, y = *i_q, px = x, py = y, r_prev = INFINITY;
    for (int it = 0; it < FM_NEWTON_MAX; it++) {
        double fd, fq, l[4], rd, rq, r, det, dx, dy;
        fm_flux(p, x, y, &fd, &fq, l);
        rd = psi_d - fd;
        rq = psi_q - fq;
        r = fabs(rd) + fabs(rq);
        if (!isfinite(r)) {
            return FM_E_NEWTON;
        }
        if (r > r_prev && it > 0) { /* the full step went too far: halve it (backtracking) */
            x = px + 0.5 * (x - px);
            y = py + 0.5 * (y - py);
            if (fabs(x - px) + fabs(y - py) < 1e-14 * (1.0 + fabs(px) + fabs(py))) {
                break;
            }
            continue;
        }
        det = l[0] * l[3] - l[1] * l[2];
        if (!(det > 0.0)) {
            return FM_E_NEWTON;
        }
        dx = (l[3] * rd - l[1] * rq) / det;
        dy = (-l[2] * rd + l[0] * rq) / det;
        px = x;
        py = y;
        r_prev = r;
        x += dx;
        y += dy;
        /* quadratic convergence: the error left after this step is ~ (curvature/slope of the map) * step^2, below
         * 1e-13 A for a step of 1e-7 A at the curvatures of a saturating map (dL/di / L < 1/A) */
        if (fabs(dx) + fabs(dy) <= 1e-7 * (1.0 + fabs(x) + fabs(y))) {
            *i_d = x;
            *i_q = y;
            return 0;
        }
    }
    /* backtracking stalled: accept only a residual at rounding level */
    {
        double fd, fq;
        fm_flux(p, px, py, &fd, &fq, NULL);
        if (fabs(psi_d - fd) + fabs(psi_q - fq) <= 1e-14 * (1.0 + fabs(psi_d) + fabs(psi_q))) {
            *i_d = px;
            *i_q = py;
            return 0;
        }
    }
    return FM_E_NEWTON;
}

static double fm_torque(const fm_params_t *p, double psi_d, double psi_q, double i_d, double i_q)
{
    return 1.5 * (double)p->pole_pairs * (psi_d * i_q - psi_q * i_d);
}

#define FM_LEVEL_OPEN 2 /* dead_level value: diode blocked, phase open */
static const double FM_EX[3] = {1.0, -0.5, -0.5};
static const double FM_EY[3] = {0.0, 0.8660254037844386, -0.8660254037844386};

/* The flux ODE of one piece: stator-frame voltage of the legs' levels (an open leg counted at the low rail) [V],
 * angle theta0 + omega_e tau, and the phase held at zero current (-1: none). */
typedef struct {
    const fm_params_t *p;
    double v_alpha, v_beta, theta0, omega_e;
    int open_leg;
} fm_rhs_t;

/* Current of phase `leg` [A] from dq currents at angle theta [rad]. */
static double leg_current(double i_d, double i_q, double theta, int leg)
{
    double sn, cs;
    dq_sincos(theta, &sn, &cs);
    return FM_EX[leg] * (i_d * cs - i_q * sn) + FM_EY[leg] * (i_d * sn + i_q * cs);
}

static int rhs(const fm_rhs_t *c, double tau, const double *psi, double *cur, double *dpsi)
{
    const fm_params_t *p = c->p;
    double sn, cs;
    int rc = fm_currents(p, psi[0], psi[1], &cur[0], &cur[1]);
    if (rc != 0) {
        return rc;
    }
    dq_sincos(c->theta0 + c->omega_e * tau, &sn, &cs);
    dpsi[0] = c->v_alpha * cs + c->v_beta * sn - p->rs * cur[0] + c->omega_e * psi[1];
    dpsi[1] = -c->v_alpha * sn + c->v_beta * cs - p->rs * cur[1] - c->omega_e * psi[0];
    if (c->open_leg >= 0) {
        /* The open terminal floats to the potential u [V] that keeps its current at zero: the rotor-frame voltage
         * gains (2/3) u h, h = R(-theta) e_x the phase's direction, and d/dt (h . i) = 0 with di/dt = L_inc^-1
         * dpsi/dt and dh/dt = omega_e (h_q, -h_d): u = -(omega_e (h_q i_d - h_d i_q) + h.G dpsi0) / ((2/3) h.G h). */
        const int x = c->open_leg;
        const double h_d = FM_EX[x] * cs + FM_EY[x] * sn;
        const double h_q = -FM_EX[x] * sn + FM_EY[x] * cs;
        double l[4], fd, fq, det, g_h_d, g_h_q, u;
        fm_flux(p, cur[0], cur[1], &fd, &fq, l);
        det = l[0] * l[3] - l[1] * l[2];
        if (!(det > 0.0)) {
            return FM_E_NEWTON;
        }
        /* G^T h, so that h.G v = (G^T h).v; G = L^-1 = [[l3, -l1], [-l2, l0]] / det */
        g_h_d = (l[3] * h_d - l[2] * h_q) / det;
        g_h_q = (-l[1] * h_d + l[0] * h_q) / det;
        u = -(c->omega_e * (h_q * cur[0] - h_d * cur[1]) + g_h_d * dpsi[0] + g_h_q * dpsi[1])
            / ((2.0 / 3.0) * (g_h_d * h_d + g_h_q * h_q));
        dpsi[0] += (2.0 / 3.0) * u * h_d;
        dpsi[1] += (2.0 / 3.0) * u * h_q;
    }
    return 0;
}

/* Dormand-Prince 5(4) tableau */
static const double A21 = 1.0 / 5.0;
static const double A31 = 3.0 / 40.0, A32 = 9.0 / 40.0;
static const double A41 = 44.0 / 45.0, A42 = -56.0 / 15.0, A43 = 32.0 / 9.0;
static const double A51 = 19372.0 / 6561.0, A52 = -25360.0 / 2187.0, A53 = 64448.0 / 6561.0, A54 = -212.0 / 729.0;
static const double A61 = 9017.0 / 3168.0, A62 = -355.0 / 33.0, A63 = 46732.0 / 5247.0, A64 = 49.0 / 176.0,
                    A65 = -5103.0 / 18656.0;
static const double B1 = 35.0 / 384.0, B3 = 500.0 / 1113.0, B4 = 125.0 / 192.0, B5 = -2187.0 / 6784.0,
                    B6 = 11.0 / 84.0;
static const double E1 = 71.0 / 57600.0, E3 = -71.0 / 16695.0, E4 = 71.0 / 1920.0, E5 = -17253.0 / 339200.0,
                    E6 = 22.0 / 525.0, E7 = -1.0 / 40.0;
static const double C2 = 1.0 / 5.0, C3 = 3.0 / 10.0, C4 = 4.0 / 5.0, C5 = 8.0 / 9.0;

/* One step of size h from (tau, psi, cur) with k1 = f(tau, psi): the new flux, its currents, f there (k7, FSAL)
 * and the error estimate as a current [A]. */
static int dopri_step(const fm_rhs_t *c, double tau, const double *psi, const double *cur, const double *k1, double h,
                      double *ynew, double *cnew, double *k7, double *err)
{
    double k2[2], k3[2], k4[2], k5[2], k6[2], y[2];
    int rc;
    cnew[0] = cur[0];
    cnew[1] = cur[1];
    for (int k = 0; k < 2; k++) y[k] = psi[k] + h * A21 * k1[k];
    if ((rc = rhs(c, tau + C2 * h, y, cnew, k2)) != 0) return rc;
    for (int k = 0; k < 2; k++) y[k] = psi[k] + h * (A31 * k1[k] + A32 * k2[k]);
    if ((rc = rhs(c, tau + C3 * h, y, cnew, k3)) != 0) return rc;
    for (int k = 0; k < 2; k++) y[k] = psi[k] + h * (A41 * k1[k] + A42 * k2[k] + A43 * k3[k]);
    if ((rc = rhs(c, tau + C4 * h, y, cnew, k4)) != 0) return rc;
    for (int k = 0; k < 2; k++) y[k] = psi[k] + h * (A51 * k1[k] + A52 * k2[k] + A53 * k3[k] + A54 * k4[k]);
    if ((rc = rhs(c, tau + C5 * h, y, cnew, k5)) != 0) return rc;
    for (int k = 0; k < 2; k++)
        y[k] = psi[k] + h * (A61 * k1[k] + A62 * k2[k] + A63 * k3[k] + A64 * k4[k] + A65 * k5[k]);
    if ((rc = rhs(c, tau + h, y, cnew, k6)) != 0) return rc;
    for (int k = 0; k < 2; k++)
        ynew[k] = psi[k] + h * (B1 * k1[k] + B3 * k3[k] + B4 * k4[k] + B5 * k5[k] + B6 * k6[k]);
    if ((rc = rhs(c, tau + h, ynew, cnew, k7)) != 0) return rc;
    *err = 0.0;
    for (int k = 0; k < 2; k++) {
        const double e = fabs(h * (E1 * k1[k] + E3 * k3[k] + E4 * k4[k] + E5 * k5[k] + E6 * k6[k] + E7 * k7[k]));
        *err = e > *err ? e : *err;
    }
    *err *= c->p->inv_l_max; /* flux error [Wb] -> bound on the current error [A] */
    return 0;
}

/* The first leg of cond_mask (conducting through a diode during dead time) whose current has reached zero at angle
 * theta, or -1. Low-rail diode (dead_level 0): the current flows out of the leg (> 0); high rail: < 0. */
static int blocked_leg(const fm_state_t *s, int cond_mask, const double *cur, double theta)
{
    for (int leg = 0; leg < 3; leg++) {
        if ((cond_mask >> leg) & 1) {
            const double sign = s->legs.dead_level[leg] == 0 ? 1.0 : -1.0;
            if (sign * leg_current(cur[0], cur[1], theta, leg) <= 0.0) {
                return leg;
            }
        }
    }
    return -1;
}

static void phase_currents_cs(double i_d, double i_q, double c, double sn, double *i)
{
    const double i_al = i_d * c - i_q * sn;
    const double i_be = i_d * sn + i_q * c;
    i[0] = i_al;
    i[1] = -0.5 * i_al + 0.5 * FM_SQRT3 * i_be;
    i[2] = -0.5 * i_al - 0.5 * FM_SQRT3 * i_be;
}

/* The trace of a piece: rows at absolute t = trace_k * dt (dt <= 0 or buf NULL: none), the piece starting at t0. */
typedef struct {
    double t0, dt;
    double *buf;
    int32_t cap;
    fm_period_stats_t *stats;
} fm_trace_t;

static int tracing(const fm_trace_t *tr)
{
    return tr != NULL && tr->dt > 0.0 && tr->buf != NULL;
}

/* One trace row at absolute time tk [s], angle theta, flux psi [Wb] and currents cur [A]. */
static int emit_row(const fm_params_t *p, fm_state_t *s, const fm_trace_t *tr, double tk, double theta,
                    const double *psi, const double *cur)
{
    double sn, c;
    double *row = ge_trace_row(tr->buf, tr->cap, FM_TRACE_COLUMNS, tr->stats);
    if (row == NULL) {
        return MK_E_TRACE_FULL;
    }
    dq_sincos(theta, &sn, &c);
    row[0] = tk;
    phase_currents_cs(cur[0], cur[1], c, sn, row + 1);
    row[4] = fm_torque(p, psi[0], psi[1], cur[0], cur[1]);
    row[5] = s->mech.omega_m;
    return ge_trace_done(tr->stats, &s->trace_k, row + 1, 3);
}

/* The rows inside the accepted step [tau, tau + h) of the piece (and before end - 0.5 ns): the flux by the step's
 * cubic Hermite interpolant of its end values and slopes k1, k7 (error about h^4/384 times the flux's fourth
 * derivative; steps are at most FM_TRACE_H_MAX while tracing), the currents by the inverse map. */
static int emit_rows(const fm_rhs_t *c, fm_state_t *s, const fm_trace_t *tr, double tau, double h, double end,
                     const double *psi0, const double *k1, const double *psi1, const double *k7, const double *cur0)
{
    for (;;) {
        const double tk = (double)s->trace_k * tr->dt;
        double tau_k = tk - tr->t0, u, h00, h10, h01, h11, y[2], cur[2];
        int rc;
        if (tau_k >= tau + h - 0.5e-9 || tau_k >= end - 0.5e-9) {
            return 0;
        }
        tau_k = tau_k < tau ? tau : tau_k;
        u = (tau_k - tau) / h;
        h00 = (2.0 * u - 3.0) * u * u + 1.0;
        h10 = ((u - 2.0) * u + 1.0) * u * h;
        h01 = (3.0 - 2.0 * u) * u * u;
        h11 = (u - 1.0) * u * u * h;
        cur[0] = cur0[0];
        cur[1] = cur0[1];
        for (int k = 0; k < 2; k++) {
            y[k] = h00 * psi0[k] + h10 * k1[k] + h01 * psi1[k] + h11 * k7[k];
        }
        if (u > 0.0 && (rc = fm_currents(c->p, y[0], y[1], &cur[0], &cur[1])) != 0) {
            return rc;
        }
        if ((rc = emit_row(c->p, s, tr, tk, c->theta0 + c->omega_e * tau_k, u > 0.0 ? y : psi0, cur)) != 0) {
            return rc;
        }
    }
}

/* Integrate the state's flux from tau0 to tau1 (seconds into the piece described by c) with error control; the
 * state's currents follow, the trace rows inside are written (tr). A conducting diode of cond_mask whose current
 * reaches zero stops the integration there (bisection to 1e-13 s): *blocked is that leg (else -1) and *tau_end the
 * time reached. */
static int integrate_to(const fm_rhs_t *c, fm_state_t *s, const fm_trace_t *tr, double tau0, double tau1,
                        int cond_mask, int *blocked, double *tau_end)
{
    double tau = tau0;
    double psi[2] = {s->psi_d, s->psi_q};
    double cur[2] = {s->i_d, s->i_q};
    double k1[2], k7[2], ynew[2], cnew[2];
    double h = s->h_last > 0.0 ? s->h_last : 1e-6;
    int rc;
    *blocked = -1;
    *tau_end = tau1;
    if (tau1 - tau0 <= 0.0) {
        return 0;
    }
    if ((rc = rhs(c, tau, psi, cur, k1)) != 0) {
        return rc;
    }
    while (tau < tau1) {
        int last;
        double err, hs;
        if (tracing(tr) && h > FM_TRACE_H_MAX) {
            h = FM_TRACE_H_MAX;
        }
        last = h >= tau1 - tau;
        if (last) {
            h = tau1 - tau;
        }
        if ((rc = dopri_step(c, tau, psi, cur, k1, h, ynew, cnew, k7, &err)) != 0) {
            return rc;
        }
        hs = err > 0.0 ? 0.9 * pow(c->p->tol_i / err, 0.2) : 5.0;
        hs = hs > 5.0 ? 5.0 : (hs < 0.2 ? 0.2 : hs);
        if (err > c->p->tol_i) {
            s->rejected++;
            h *= hs;
            if (h < FM_H_MIN) {
                return FM_E_STEP;
            }
            continue;
        }
        if (cond_mask && blocked_leg(s, cond_mask, cnew, c->theta0 + c->omega_e * (tau + h)) >= 0) {
            double lo = 0.0, hi = h;
            for (int it = 0; it < 80 && hi - lo > 1e-13; it++) {
                const double mid = 0.5 * (lo + hi);
                if ((rc = dopri_step(c, tau, psi, cur, k1, mid, ynew, cnew, k7, &err)) != 0) {
                    return rc;
                }
                if (blocked_leg(s, cond_mask, cnew, c->theta0 + c->omega_e * (tau + mid)) >= 0) {
                    hi = mid;
                } else {
                    lo = mid;
                }
            }
            if ((rc = dopri_step(c, tau, psi, cur, k1, hi, ynew, cnew, k7, &err)) != 0) {
                return rc;
            }
            *blocked = blocked_leg(s, cond_mask, cnew, c->theta0 + c->omega_e * (tau + hi));
            *tau_end = tau + hi;
            if (tracing(tr) && (rc = emit_rows(c, s, tr, tau, hi, tau + hi, psi, k1, ynew, k7, cur)) != 0) {
                return rc;
            }
            s->steps++;
            s->psi_d = ynew[0];
            s->psi_q = ynew[1];
            s->i_d = cnew[0];
            s->i_q = cnew[1];
            return 0;
        }
        if (tracing(tr) && (rc = emit_rows(c, s, tr, tau, h, tau1, psi, k1, ynew, k7, cur)) != 0) {
            return rc;
        }
        tau = last ? tau1 : tau + h;
        psi[0] = ynew[0];
        psi[1] = ynew[1];
        cur[0] = cnew[0];
        cur[1] = cnew[1];
        k1[0] = k7[0];
        k1[1] = k7[1];
        s->steps++;
        if (!last) {
            s->h_last = h * hs;
        }
        h *= hs;
    }
    s->psi_d = psi[0];
    s->psi_q = psi[1];
    s->i_d = cur[0];
    s->i_q = cur[1];
    return 0;
}

/* No current can flow (two or three phases open): the flux rests at the map's zero-current flux. */
static int run_open(const fm_params_t *p, fm_state_t *s, const fm_trace_t *tr, double piece, double omega_e)
{
    double psi[2], cur[2] = {0.0, 0.0};
    s->i_d = 0.0;
    s->i_q = 0.0;
    fm_flux(p, 0.0, 0.0, &s->psi_d, &s->psi_q, NULL);
    psi[0] = s->psi_d;
    psi[1] = s->psi_q;
    while (tracing(tr)) {
        const double tk = (double)s->trace_k * tr->dt;
        int rc;
        if (tk - tr->t0 >= piece - 0.5e-9) {
            break;
        }
        rc = emit_row(p, s, tr, tk, s->theta_e + omega_e * (tk - tr->t0 > 0.0 ? tk - tr->t0 : 0.0), psi, cur);
        if (rc != 0) {
            return rc;
        }
    }
    return 0;
}

/* One interval of constant gate levels (gate_edges.c) as the mechanics cuts it into constant-speed pieces
 * (mechanics.h): the kernel's part of the state and the trace. */
typedef struct {
    ge_run_t run; /* the mechanics, the trace, the stats, the gate levels (gate_edges.h) */
    const fm_params_t *p;
    fm_state_t *s;
} fm_ctx_t;

static double torque_cb(const void *ctx)
{
    const fm_ctx_t *x = (const fm_ctx_t *)ctx;
    const fm_state_t *s = x->s;
    return fm_torque(x->p, s->psi_d, s->psi_q, s->i_d, s->i_q);
}

/* One piece from absolute time t0 [s] at the constant speed omega_m [rad/s]; legs in dead time conduct through the
 * diode their current's sign chose until that current reaches zero (the piece then ends there), then the phase
 * opens. */
static int piece_cb(void *ctx, double t0, double *piece_io, double omega_m)
{
    fm_ctx_t *x = (fm_ctx_t *)ctx;
    const fm_params_t *p = x->p;
    fm_state_t *s = x->s;
    double piece = *piece_io;
    int blocked = -1, rc;
    ge_levels_t lv;
    fm_rhs_t c;
    fm_trace_t tr;
    ge_levels_at(&x->run, 3, t0, &s->legs, FM_LEVEL_OPEN, &lv);
    c.p = p;
    c.v_alpha = p->vdc / 3.0 * (2.0 * lv.level[0] - lv.level[1] - lv.level[2]);
    c.v_beta = p->vdc / FM_SQRT3 * (lv.level[1] - lv.level[2]);
    c.theta0 = s->theta_e;
    c.omega_e = (double)p->pole_pairs * omega_m;
    c.open_leg = lv.n_open == 1 ? lv.open_leg : -1;
    tr.t0 = t0;
    tr.dt = x->run.trace_dt;
    tr.buf = x->run.trace;
    tr.cap = x->run.trace_cap;
    tr.stats = x->run.stats;
    if (lv.n_open >= 2) {
        rc = run_open(p, s, &tr, piece, c.omega_e);
    } else {
        rc = integrate_to(&c, s, &tr, 0.0, piece, lv.cond_mask, &blocked, &piece);
    }
    if (rc != 0) {
        return rc;
    }
    s->theta_e = dq_wrap_angle(s->theta_e + c.omega_e * piece);
    if (blocked >= 0) {
        s->legs.dead_level[blocked] = FM_LEVEL_OPEN;
        x->run.stats->open_phase_events++;
    }
    *piece_io = piece;
    return 0;
}

/* Diode by the current's sign, as plant.c; no current -> the phase is open (gate_edges.h). */
static double leg_current_cb(const void *ctx, int leg)
{
    const fm_state_t *s = ((const fm_ctx_t *)ctx)->s;
    return leg_current(s->i_d, s->i_q, s->theta_e, leg);
}

static const ge_kind_t FM_GATES = {3, 7, GE_MAX_SUBINTERVALS, FM_MAX_EVENTS, piece_cb, torque_cb, leg_current_cb,
                                   FM_LEVEL_OPEN};

int fm_advance(const fm_params_t *p, fm_state_t *s, const int32_t *states, const int64_t *durations_ns, int32_t n,
               const mech_load_t *load, double trace_dt, double *trace, int32_t trace_cap, fm_period_stats_t *stats)
{
    fm_ctx_t c;
    ge_run_init(&c.run, &p->mech, &s->mech, trace_dt, trace, trace_cap, stats);
    c.p = p;
    c.s = s;
    return ge_advance(&FM_GATES, &c, states, durations_ns, n, load, p->t_mpw, p->t_dead, &s->t_ns, &s->gate,
                      &s->legs, stats);
}

void fm_sample(const fm_params_t *p, const fm_state_t *s, mk_sample_t *out)
{
    const double co = cos(s->theta_e);
    const double sn = sin(s->theta_e);
    phase_currents_cs(s->i_d, s->i_q, co, sn, out->i);
    out->i_d = s->i_d;
    out->i_q = s->i_q;
    out->theta_e = s->theta_e;
    out->omega_m = s->mech.omega_m;
    out->torque = fm_torque(p, s->psi_d, s->psi_q, s->i_d, s->i_q);
}

/* the machine-kernel table (machine_kernel.h) */
MK_KERNEL_TABLE(fm, fm_params_t, fm_state_t, fm_advance, fm_sample, "saturated PMSM (flux map)", 3, 7, FM_TRACE_COLUMNS)
