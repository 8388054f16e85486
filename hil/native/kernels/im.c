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
    double *row;
    if (stats->trace_n >= trace_cap) {
        return MK_E_TRACE_FULL;
    }
    row = trace + (ptrdiff_t)stats->trace_n * IM_TRACE_COLUMNS;
    row[0] = tk;
    phase_currents(creal(i_s), cimag(i_s), row + 1);
    for (int k = 1; k <= 3; k++) {
        if (fabs(row[k]) > stats->peak_current) {
            stats->peak_current = fabs(row[k]);
        }
    }
    row[4] = torque_of(p, psi_s, psi_r);
    row[5] = s->omega_m;
    stats->trace_n++;
    s->trace_k++;
    return 0;
}

/* Integrate h seconds from t_abs with constant gate levels (legs in dead time at their diode level). */
static int integrate(const im_params_t *p, im_state_t *s, double t_abs, double h, double t_load0, double t_load_slope,
                     double t_period0, double trace_dt, double *trace, int32_t trace_cap, im_period_stats_t *stats,
                     const int *gate_level)
{
    double done = 0.0;
    const double inv_j = p->inertia_mode ? 1.0 / p->j : 0.0; /* [1/(kg*m^2)] */
    while (done < h - 0.5e-9) {
        double piece = h - done;
        const double omega_e = (double)p->pole_pairs * s->omega_m;
        const double t0 = t_abs + done;
        double complex x[2], h0[2], E[2][2];
        double u_al, u_be, te0 = 0.0;
        int levels = 0;
        im_seg_t g;
        for (int leg = 0; leg < 3; leg++) {
            const int lvl = t0 < s->dead_until[leg] - 0.5e-9 ? s->dead_level[leg] : gate_level[leg];
            levels |= lvl << (2 - leg);
        }
        if (p->inertia_mode && p->max_piece > 0.0 && piece > p->max_piece) {
            piece = p->max_piece;
        }
        x[0] = s->psi_s[0] + IM_J * s->psi_s[1];
        x[1] = s->psi_r[0] + IM_J * s->psi_r[1];
        if (p->inertia_mode) {
            te0 = torque_of(p, x[0], x[1]);
        }
        leg_voltage(p->vdc, levels, &u_al, &u_be);
        seg_setup(p, omega_e, u_al, u_be, &g);
        h0[0] = x[0] - g.x_p[0];
        h0[1] = x[1] - g.x_p[1];
        if (trace_dt > 0.0 && trace != NULL) {
            double complex y[2], E_dt[2][2];
            int fresh = 1;
            seg_exp(&g, trace_dt, E_dt);
            for (;;) {
                const double tk = (double)s->trace_k * trace_dt;
                double tau = tk - t0;
                int rc;
                if (tau >= piece - 0.5e-9) { /* grid and edges are ns-aligned */
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
        seg_exp(&g, piece, E);
        mat_vec(E, h0, x);
        x[0] += g.x_p[0];
        x[1] += g.x_p[1];
        s->psi_s[0] = creal(x[0]);
        s->psi_s[1] = cimag(x[0]);
        s->psi_r[0] = creal(x[1]);
        s->psi_r[1] = cimag(x[1]);
        s->theta_e = dq_wrap_angle(s->theta_e + omega_e * piece);
        if (p->inertia_mode) {
            const double te1 = torque_of(p, x[0], x[1]);
            const double t_load = t_load0 + t_load_slope * (t0 + 0.5 * piece - t_period0);
            /* trapezoidal torque, implicit friction: (1 + k) w1 = (1 - k) w0 + piece (Te - Tl) / J */
            const double k = 0.5 * piece * p->b * inv_j;
            const double w1 = s->omega_m * (1.0 - k) + piece * (0.5 * (te0 + te1) - t_load) * inv_j;
            s->omega_m = k != 0.0 ? w1 / (1.0 + k) : w1;
        }
        done += piece;
    }
    return 0;
}

static double phase_current(const im_params_t *p, const im_state_t *s, int leg)
{
    double i[3];
    phase_currents((s->psi_s[0] - s->psi_r[0]) / p->lsigma, (s->psi_s[1] - s->psi_r[1]) / p->lsigma, i);
    return i[leg];
}

/* Callbacks for the shared period driver (gate_edges.c). */
typedef struct {
    const im_params_t *p;
    im_state_t *s;
    double trace_dt;
    double *trace;
    int32_t trace_cap;
    im_period_stats_t *stats;
} im_run_ctx_t;

static int im_integrate_cb(void *ctx, double t, double h, double load_val, double load_slope, double load_ref,
                           const int *gate_level)
{
    im_run_ctx_t *c = (im_run_ctx_t *)ctx;
    return integrate(c->p, c->s, t, h, load_val, load_slope, load_ref, c->trace_dt, c->trace, c->trace_cap, c->stats,
                     gate_level);
}

/* Sign rule (as the six-phase kernel): current out of the leg -> lower diode; into it -> upper diode; exactly
 * zero -> the new level (no open-phase model). */
static int im_dead_level_cb(void *ctx, int leg, int new_level)
{
    im_run_ctx_t *c = (im_run_ctx_t *)ctx;
    const double i_ph = phase_current(c->p, c->s, leg);
    return i_ph > 0.0 ? 0 : (i_ph < 0.0 ? 1 : new_level);
}

int im_advance(const im_params_t *p, im_state_t *s, const int32_t *states, const int64_t *durations_ns, int32_t n,
               double t_load0, double t_load_slope, const double *load_bp, int32_t n_load_bp, double trace_dt,
               double *trace, int32_t trace_cap, im_period_stats_t *stats)
{
    dq_event_t ev[IM_MAX_EVENTS];
    int n_ev = 0;
    const double t_start = (double)s->t_ns * 1e-9;
    int64_t total_ns = 0;
    const double t_lim = 2.0 * p->t_dead + p->t_mpw;

    ge_stats_reset(stats);
    if (n < 1 || n > IM_MAX_SUBINTERVALS || !(p->rs > 0.0) || !(p->rr > 0.0) || !(p->lsigma > 0.0) ||
        !(p->lm > 0.0)) {
        stats->error = MK_E_ARGS;
        return MK_E_ARGS;
    }
    for (int k = 0; k < n; k++) {
        if (durations_ns[k] < 0 || states[k] < 0 || states[k] > 7) {
            stats->error = MK_E_ARGS;
            return MK_E_ARGS;
        }
    }
    n_ev = ge_plan(3, s->gate, states, durations_ns, n, t_start, p->t_mpw, t_lim, s->last_edge_t, ev, n_ev,
                   IM_MAX_EVENTS, stats, &total_ns);
    {
        im_run_ctx_t c = {p, s, trace_dt, trace, trace_cap, stats};
        const int rc = ge_run_period(3, t_start, t_start + (double)total_ns * 1e-9, p->t_dead, ev, n_ev, IM_MAX_EVENTS,
                                     t_load0, t_load_slope, load_bp, n_load_bp, &s->gate, s->dead_until,
                                     s->dead_level, im_integrate_cb, im_dead_level_cb, &c);
        if (rc != 0) {
            stats->error = rc;
            return rc;
        }
    }
    s->t_ns += (uint64_t)total_ns;
    return 0;
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
    out->omega_m = s->omega_m;
    out->torque = 1.5 * (double)p->pole_pairs * (s->psi_s[0] * i_be - s->psi_s[1] * i_al);
}

/* --- the machine-kernel table (machine_kernel.h) ------------------------------------------------------------ */
static int im_k_advance(const void *p, void *s, const int32_t *states, const int64_t *durations_ns, int32_t n,
                        double t_load0, double t_load_slope, const double *load_bp, int32_t n_load_bp,
                        double trace_dt, double *trace, int32_t trace_cap, ge_period_stats_t *stats)
{
    return im_advance((const im_params_t *)p, (im_state_t *)s, states, durations_ns, n, t_load0, t_load_slope,
                      load_bp, n_load_bp, trace_dt, trace, trace_cap, stats);
}

static void im_k_sample(const void *p, const void *s, mk_sample_t *out)
{
    im_sample((const im_params_t *)p, (const im_state_t *)s, out);
}

static void im_k_hold_speed(void *params, void *state, double omega_m)
{
    ((im_params_t *)params)->inertia_mode = 0;
    ((im_state_t *)state)->omega_m = omega_m;
}

static uint64_t im_k_time_ns(const void *state)
{
    return ((const im_state_t *)state)->t_ns;
}

static const mk_kernel_t IM_KERNEL = {
    MK_ABI_VERSION, "three-phase induction machine", 3, 7, IM_TRACE_COLUMNS, sizeof(im_params_t),
    sizeof(im_state_t), im_k_advance, im_k_sample, im_k_hold_speed, im_k_time_ns,
};

const mk_kernel_t *im_kernel(void)
{
    return &IM_KERNEL;
}
