/* Exact induction machine + two-level inverter plant kernel; see im.h and docs/plant.md. */
#include "im.h"
#include "dq_segment.h"
#include "gate_edges.h"

#include <complex.h>
#include <math.h>
#include <stddef.h>

#define IM_SQRT3 1.7320508075688772935274463415059
#define IM_MAX_EVENTS 64
#define IM_J ((double complex)I)

/* Closed form of one constant-voltage piece at constant speed: x(tau) = x_p + exp(m tau) (C I + S M) h0,
 * M = A - m I, M*M = r2 I, C = cosh(sqrt(r2) tau), S = sinh(sqrt(r2) tau) / sqrt(r2). */
typedef struct {
    double complex x_p[2];   /* equilibrium (psi_s, psi_R) [Wb] */
    double complex m, r2;    /* tr(A) / 2 [1/s], (A - m I)^2 / I [1/s^2] */
    double complex M[2][2];  /* A - m I [1/s] */
} im_seg_t;

static void seg_setup(const im_params_t *p, double omega_e, double u_al, double u_be, im_seg_t *g)
{
    const double a11 = -p->rs / p->lsigma, a12 = p->rs / p->lsigma, a21 = p->rr / p->lsigma;
    const double complex a22 = -p->rr / p->lsigma - p->rr / p->lm + IM_J * omega_e;
    const double complex det = a11 * a22 - a12 * a21;
    const double complex us = u_al + IM_J * u_be;
    const double complex half = 0.5 * (a11 - a22);
    g->x_p[0] = -a22 * us / det; /* -A^-1 (us, 0) */
    g->x_p[1] = a21 * us / det;
    g->m = 0.5 * (a11 + a22);
    g->M[0][0] = half;
    g->M[0][1] = a12;
    g->M[1][0] = a21;
    g->M[1][1] = -half;
    g->r2 = half * half + a12 * a21;
}

/* exp(A tau) as the 2x2 complex matrix E. */
static void seg_exp(const im_seg_t *g, double tau, double complex E[2][2])
{
    const double complex z = g->r2 * tau * tau;
    const double complex em = cexp(g->m * tau);
    double complex c, s;
    if (cabs(z) < 1e-4) { /* series of cosh and sinh(r tau)/r: truncation < 1e-18 */
        c = 1.0 + z / 2.0 + z * z / 24.0 + z * z * z / 720.0;
        s = tau * (1.0 + z / 6.0 + z * z / 120.0 + z * z * z / 5040.0);
    } else {
        const double complex r = csqrt(g->r2);
        c = ccosh(r * tau);
        s = csinh(r * tau) / r;
    }
    E[0][0] = em * (c + s * g->M[0][0]);
    E[0][1] = em * (s * g->M[0][1]);
    E[1][0] = em * (s * g->M[1][0]);
    E[1][1] = em * (c + s * g->M[1][1]);
}

/* y = E h */
static void mat_vec(double complex E[2][2], const double complex h[2], double complex y[2])
{
    const double complex y0 = E[0][0] * h[0] + E[0][1] * h[1];
    const double complex y1 = E[1][0] * h[0] + E[1][1] * h[1];
    y[0] = y0;
    y[1] = y1;
}

static double torque_of(const im_params_t *p, double complex psi_s, double complex psi_r)
{
    const double complex i_s = (psi_s - psi_r) / p->lsigma;
    return 1.5 * (double)p->pole_pairs * (creal(psi_s) * cimag(i_s) - cimag(psi_s) * creal(i_s));
}

static void phase_currents(double i_al, double i_be, double *i)
{
    i[0] = i_al;
    i[1] = -0.5 * i_al + 0.5 * IM_SQRT3 * i_be;
    i[2] = -0.5 * i_al - 0.5 * IM_SQRT3 * i_be;
}

/* Stator-frame voltage [V] of leg levels (bit 2: a, bit 1: b, bit 0: c). */
static void leg_voltage(double vdc, int levels, double *v_alpha, double *v_beta)
{
    const double sa = (double)((levels >> 2) & 1), sb = (double)((levels >> 1) & 1), sc = (double)(levels & 1);
    *v_alpha = vdc / 3.0 * (2.0 * sa - sb - sc);
    *v_beta = vdc / IM_SQRT3 * (sb - sc);
}

static int emit_row(const im_params_t *p, im_state_t *s, double tk, double complex psi_s, double complex psi_r,
                    double *trace, int32_t trace_cap, im_period_stats_t *stats)
{
    const double complex i_s = (psi_s - psi_r) / p->lsigma;
    double *row = ge_trace_row(trace, trace_cap, IM_TRACE_COLUMNS, stats);
    if (row == NULL) {
        return MK_E_TRACE_FULL;
    }
    row[0] = tk;
    phase_currents(creal(i_s), cimag(i_s), row + 1);
    row[4] = torque_of(p, psi_s, psi_r);
    row[5] = s->mech.omega_m;
    return ge_trace_done(stats, &s->trace_k, row + 1, 3);
}

#define IM_LEVEL_OPEN 2     /* dead_level value: diode blocked, phase open */
#define IM_OPEN_STEP 25e-9  /* RK4 step while a phase is open [s] */

/* Unit phase directions a_k (stator frame) of phases a, b, c. */
static const double IM_EX[3] = {1.0, -0.5, -0.5};
static const double IM_EY[3] = {0.0, 0.8660254037844386, -0.8660254037844386};

/* Phase current of `leg` [A] for the fluxes (psi_s, psi_r) [Wb]. */
static double leg_current_of(const im_params_t *p, double complex psi_s, double complex psi_r, int leg)
{
    const double complex i_s = (psi_s - psi_r) / p->lsigma;
    return IM_EX[leg] * creal(i_s) + IM_EY[leg] * cimag(i_s);
}

/* The closed form of one piece as ge_first_blocking reads it: the machine, the segment and its initial homogeneous
 * part. */
typedef struct {
    const im_params_t *p;
    const im_seg_t *g;
    const double complex *h0;
} im_piece_form_t;

static double im_current_at(const void *ctx, double tau, int leg)
{
    const im_piece_form_t *f = (const im_piece_form_t *)ctx;
    double complex E[2][2], y[2];
    seg_exp(f->g, tau, E);
    mat_vec(E, f->h0, y);
    return leg_current_of(f->p, f->g->x_p[0] + y[0], f->g->x_p[1] + y[1], leg);
}

/* No phase open: the closed form over *piece (shortened to the first diode blocking: *blocked its leg). */
static int piece_closed(const im_params_t *p, im_state_t *s, double t0, double *piece, int levels, int cond_mask,
                        double omega_e, double trace_dt, double *trace, int32_t trace_cap, im_period_stats_t *stats,
                        int *blocked)
{
    double complex x[2], h0[2], E[2][2];
    double u_al, u_be;
    im_seg_t g;
    x[0] = s->psi_s[0] + IM_J * s->psi_s[1];
    x[1] = s->psi_r[0] + IM_J * s->psi_r[1];
    leg_voltage(p->vdc, levels, &u_al, &u_be);
    seg_setup(p, omega_e, u_al, u_be, &g);
    h0[0] = x[0] - g.x_p[0];
    h0[1] = x[1] - g.x_p[1];
    if (cond_mask) {
        const im_piece_form_t form = {p, &g, h0};
        *piece = ge_first_blocking(im_current_at, &form, 3, *piece, cond_mask, s->legs.dead_level, blocked);
    }
    if (trace_dt > 0.0 && trace != NULL) {
        double complex y[2], E_dt[2][2];
        int fresh = 1;
        seg_exp(&g, trace_dt, E_dt);
        for (;;) {
            const double tk = (double)s->trace_k * trace_dt;
            double tau = tk - t0;
            int rc;
            if (tau >= *piece - 0.5e-9) { /* grid and edges are ns-aligned */
                break;
            }
            if (fresh) { /* the first row of the piece from the closed form, then steps of exp(A dt) */
                tau = tau < 0.0 ? 0.0 : tau;
                seg_exp(&g, tau, E);
                mat_vec(E, h0, y);
                fresh = 0;
            } else {
                mat_vec(E_dt, y, y);
            }
            rc = emit_row(p, s, tk, g.x_p[0] + y[0], g.x_p[1] + y[1], trace, trace_cap, stats);
            if (rc != 0) {
                return rc;
            }
        }
    }
    seg_exp(&g, *piece, E);
    mat_vec(E, h0, x);
    x[0] += g.x_p[0];
    x[1] += g.x_p[1];
    s->psi_s[0] = creal(x[0]);
    s->psi_s[1] = cimag(x[0]);
    s->psi_r[0] = creal(x[1]);
    s->psi_r[1] = cimag(x[1]);
    return 0;
}

/* d/dt of the loop current i (into phase y, out of z, h = a_y - a_z) and of psi_R with the third phase open:
 * 2 L_sigma di/dt = v_yz - 2 (Rs + RR) i + Re{conj(h) (RR/L_M - j omega_e) psi_R},
 * d psi_R/dt = (2/3) RR h i - (RR/L_M - j omega_e) psi_R. */
static void open_deriv(const im_params_t *p, double complex h, double v_yz, double complex lam, double i,
                       double complex psi_r, double *di, double complex *dpsi)
{
    *di = (v_yz - 2.0 * (p->rs + p->rr) * i + creal(conj(h) * lam * psi_r)) / (2.0 * p->lsigma);
    *dpsi = (2.0 / 3.0) * p->rr * h * i - lam * psi_r;
}

/* One phase open: RK4 (steps <= 25 ns) of the loop current and psi_R over *piece; a connected leg conducting
 * through its diode blocks when the loop current crosses zero (the piece ends there, *blocked its leg). */
static int piece_one_open(const im_params_t *p, im_state_t *s, double t0, double *piece, int levels, int open_leg,
                          int cond_mask, double omega_e, double trace_dt, double *trace, int32_t trace_cap,
                          im_period_stats_t *stats, int *blocked)
{
    const int y = (open_leg + 1) % 3, z = (open_leg + 2) % 3;
    const double complex h = (IM_EX[y] - IM_EX[z]) + IM_J * (IM_EY[y] - IM_EY[z]);
    const double v_yz = p->vdc * (double)(((levels >> (2 - y)) & 1) - ((levels >> (2 - z)) & 1));
    const double complex lam = p->rr / p->lm - IM_J * omega_e;
    const int conducting = ((cond_mask >> y) & 1) ? y : (((cond_mask >> z) & 1) ? z : -1);
    double complex psi_r = s->psi_r[0] + IM_J * s->psi_r[1];
    const double complex i_s0 = ((s->psi_s[0] - s->psi_r[0]) + IM_J * (s->psi_s[1] - s->psi_r[1])) / p->lsigma;
    double i = 0.5 * creal(conj(h) * i_s0); /* projection onto the loop (|h|^2 = 3) */
    double tau = 0.0;
    while (tau < *piece - 0.5e-9) {
        double stop = *piece, hstep;
        int n_sub, crossed = 0;
        if (trace_dt > 0.0 && trace != NULL) {
            double tk = (double)s->trace_k * trace_dt;
            if (tk - (t0 + tau) < 0.5e-9) {
                const int rc = emit_row(p, s, tk, p->lsigma * (2.0 / 3.0) * h * i + psi_r, psi_r, trace, trace_cap,
                                        stats);
                if (rc != 0) {
                    return rc;
                }
                tk = (double)s->trace_k * trace_dt;
            }
            if (tk - t0 < stop) {
                stop = tk - t0;
            }
        }
        n_sub = (int)ceil((stop - tau) / IM_OPEN_STEP - 1e-9);
        n_sub = n_sub < 1 ? 1 : n_sub;
        hstep = (stop - tau) / (double)n_sub;
        for (int k = 0; k < n_sub; k++) {
            const double i_prev = i;
            double k1, k2, k3, k4;
            double complex m1, m2, m3, m4;
            open_deriv(p, h, v_yz, lam, i, psi_r, &k1, &m1);
            open_deriv(p, h, v_yz, lam, i + 0.5 * hstep * k1, psi_r + 0.5 * hstep * m1, &k2, &m2);
            open_deriv(p, h, v_yz, lam, i + 0.5 * hstep * k2, psi_r + 0.5 * hstep * m2, &k3, &m3);
            open_deriv(p, h, v_yz, lam, i + hstep * k3, psi_r + hstep * m3, &k4, &m4);
            i += hstep / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
            psi_r += hstep / 6.0 * (m1 + 2.0 * m2 + 2.0 * m3 + m4);
            if (conducting >= 0 && ((i_prev > 0.0 && i <= 0.0) || (i_prev < 0.0 && i >= 0.0))) {
                i = 0.0; /* the diode blocks: no current from here */
                *blocked = conducting;
                *piece = tau + (double)(k + 1) * hstep;
                crossed = 1;
                break;
            }
        }
        tau = crossed ? *piece : stop;
    }
    {
        const double complex psi_s = p->lsigma * (2.0 / 3.0) * h * i + psi_r;
        s->psi_s[0] = creal(psi_s);
        s->psi_s[1] = cimag(psi_s);
        s->psi_r[0] = creal(psi_r);
        s->psi_r[1] = cimag(psi_r);
    }
    return 0;
}

/* Two or three phases open: no current; psi_R decays freely (exactly), psi_s = psi_R. */
static int piece_no_current(const im_params_t *p, im_state_t *s, double t0, double piece, double omega_e,
                            double trace_dt, double *trace, int32_t trace_cap, im_period_stats_t *stats)
{
    const double complex lam = -p->rr / p->lm + IM_J * omega_e;
    const double complex psi0 = s->psi_r[0] + IM_J * s->psi_r[1];
    double complex psi;
    while (trace_dt > 0.0 && trace != NULL) {
        const double tk = (double)s->trace_k * trace_dt;
        const double tau = tk - t0 > 0.0 ? tk - t0 : 0.0;
        int rc;
        if (tk - t0 >= piece - 0.5e-9) {
            break;
        }
        psi = cexp(lam * tau) * psi0;
        rc = emit_row(p, s, tk, psi, psi, trace, trace_cap, stats);
        if (rc != 0) {
            return rc;
        }
    }
    psi = cexp(lam * piece) * psi0;
    s->psi_s[0] = s->psi_r[0] = creal(psi);
    s->psi_s[1] = s->psi_r[1] = cimag(psi);
    return 0;
}

/* One interval of constant gate levels (gate_edges.c) as the mechanics cuts it into constant-speed pieces
 * (mechanics.h): the kernel's part of the state and the trace. */
typedef struct {
    ge_run_t run; /* the mechanics, the trace, the stats, the gate levels (gate_edges.h) */
    const im_params_t *p;
    im_state_t *s;
} im_run_ctx_t;

static double im_torque_cb(const void *ctx)
{
    const im_run_ctx_t *c = (const im_run_ctx_t *)ctx;
    const im_state_t *s = c->s;
    return torque_of(c->p, s->psi_s[0] + IM_J * s->psi_s[1], s->psi_r[0] + IM_J * s->psi_r[1]);
}

/* One piece from absolute time t0 [s] at the constant speed omega_m [rad/s]; legs in dead time conduct through the
 * diode the current's sign picked at the edge until that current reaches zero (the piece then ends there), then
 * the phase is open. */
static int im_piece_cb(void *ctx, double t0, double *piece, double omega_m)
{
    im_run_ctx_t *c = (im_run_ctx_t *)ctx;
    const im_params_t *p = c->p;
    im_state_t *s = c->s;
    const double omega_e = (double)p->pole_pairs * omega_m;
    int blocked = -1, rc;
    ge_levels_t lv;
    ge_levels_at(&c->run, 3, t0, &s->legs, IM_LEVEL_OPEN, &lv);
    if (lv.n_open == 0) {
        rc = piece_closed(p, s, t0, piece, lv.code, lv.cond_mask, omega_e, c->run.trace_dt, c->run.trace, c->run.trace_cap,
                          c->run.stats, &blocked);
    } else if (lv.n_open == 1) {
        rc = piece_one_open(p, s, t0, piece, lv.code, lv.open_leg, lv.cond_mask, omega_e, c->run.trace_dt, c->run.trace,
                            c->run.trace_cap, c->run.stats, &blocked);
    } else {
        rc = piece_no_current(p, s, t0, *piece, omega_e, c->run.trace_dt, c->run.trace, c->run.trace_cap, c->run.stats);
    }
    if (rc != 0) {
        return rc;
    }
    if (blocked >= 0) {
        s->legs.dead_level[blocked] = IM_LEVEL_OPEN;
        c->run.stats->open_phase_events++;
    }
    s->theta_e = dq_wrap_angle(s->theta_e + omega_e * *piece);
    return 0;
}

static double phase_current(const im_params_t *p, const im_state_t *s, int leg)
{
    double i[3];
    phase_currents((s->psi_s[0] - s->psi_r[0]) / p->lsigma, (s->psi_s[1] - s->psi_r[1]) / p->lsigma, i);
    return i[leg];
}

/* Diode by the current's sign (as the three-phase PMSM kernel); no current -> the phase is open (gate_edges.h). */
static double im_leg_current_cb(const void *ctx, int leg)
{
    const im_run_ctx_t *c = (const im_run_ctx_t *)ctx;
    return phase_current(c->p, c->s, leg);
}

static const ge_kind_t IM_GATES = {3, 7, IM_MAX_SUBINTERVALS, IM_MAX_EVENTS, im_piece_cb, im_torque_cb,
                                   im_leg_current_cb, IM_LEVEL_OPEN};

int im_advance(const im_params_t *p, im_state_t *s, const int32_t *states, const int64_t *durations_ns, int32_t n,
               const mech_load_t *load, double trace_dt, double *trace, int32_t trace_cap, im_period_stats_t *stats)
{
    im_run_ctx_t c;
    if (!(p->rs > 0.0) || !(p->rr > 0.0) || !(p->lsigma > 0.0) || !(p->lm > 0.0)) {
        return ge_reject(stats, MK_E_ARGS);
    }
    ge_run_init(&c.run, &p->mech, &s->mech, trace_dt, trace, trace_cap, stats);
    c.p = p;
    c.s = s;
    return ge_advance(&IM_GATES, &c, states, durations_ns, n, load, p->t_mpw, p->t_dead, &s->t_ns, &s->gate,
                      &s->legs, stats);
}

void im_sample(const im_params_t *p, const im_state_t *s, mk_sample_t *out)
{
    const double i_al = (s->psi_s[0] - s->psi_r[0]) / p->lsigma;
    const double i_be = (s->psi_s[1] - s->psi_r[1]) / p->lsigma;
    const double psi_mag = sqrt(s->psi_r[0] * s->psi_r[0] + s->psi_r[1] * s->psi_r[1]);
    double co, sn;
    if (psi_mag > 1e-9) { /* the rotor-flux frame */
        co = s->psi_r[0] / psi_mag;
        sn = s->psi_r[1] / psi_mag;
    } else {
        co = cos(s->theta_e);
        sn = sin(s->theta_e);
    }
    phase_currents(i_al, i_be, out->i);
    out->i_d = i_al * co + i_be * sn;
    out->i_q = -i_al * sn + i_be * co;
    out->theta_e = s->theta_e;
    out->omega_m = s->mech.omega_m;
    out->torque = 1.5 * (double)p->pole_pairs * (s->psi_s[0] * i_be - s->psi_s[1] * i_al);
}

/* the machine-kernel table (machine_kernel.h) */
MK_KERNEL_TABLE(im, im_params_t, im_state_t, im_advance, im_sample, "three-phase induction machine", 3, 7,
                IM_TRACE_COLUMNS)
