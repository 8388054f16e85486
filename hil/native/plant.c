/* Exact PMSM + two-level inverter plant kernel; see plant.h. */
#include "plant.h"

#include <complex.h>
#include <math.h>
#include <stddef.h>

#define PL_TWO_PI 6.283185307179586476925286766559
#define PL_SQRT3 1.7320508075688772935274463415059
#define PL_MAX_EVENTS 64
#define PL_J ((double complex)I)

/* Closed-form solution of di/dt = A i + u(t) over one sub-interval with constant stator voltage. */
typedef struct {
    double m, delta;          /* A = m I + M, M*M = delta I */
    double M00, M01, M10, M11;
    double x0_const[2];       /* constant particular solution [A] */
    double complex z[2];      /* rotating particular solution amplitude [A] */
    double a0;                /* angle of the stator voltage relative to d at tau = 0 [rad] */
    double omega_e;           /* electrical speed [rad/s] */
    double h0[2];             /* initial homogeneous part x0 - x_p(0) [A] */
} pl_segment_t;

double pl_torque(const pl_params_t *p, double i_d, double i_q)
{
    return 1.5 * (double)p->pole_pairs * (p->psi_f * i_q + (p->ld - p->lq) * i_d * i_q);
}

void pl_phase_currents(double i_d, double i_q, double theta_e, double *i_a, double *i_b, double *i_c)
{
    double c = cos(theta_e), s = sin(theta_e);
    double i_alpha = i_d * c - i_q * s;
    double i_beta = i_d * s + i_q * c;
    *i_a = i_alpha;
    *i_b = -0.5 * i_alpha + 0.5 * PL_SQRT3 * i_beta;
    *i_c = -0.5 * i_alpha - 0.5 * PL_SQRT3 * i_beta;
}

static double wrap_angle(double theta)
{
    theta = fmod(theta, PL_TWO_PI);
    if (theta < 0.0) {
        theta += PL_TWO_PI;
    }
    return theta;
}

/* Stator-frame voltage [V] of leg levels (bit 2: a, bit 1: b, bit 0: c). */
static void leg_voltage(double vdc, int levels, double *v_alpha, double *v_beta)
{
    double sa = (double)((levels >> 2) & 1), sb = (double)((levels >> 1) & 1), sc = (double)(levels & 1);
    *v_alpha = vdc / 3.0 * (2.0 * sa - sb - sc);
    *v_beta = vdc / PL_SQRT3 * (sb - sc);
}

static void segment_setup(const pl_params_t *p, double omega_e, double theta0, double v_alpha, double v_beta,
                          double i_d0, double i_q0, pl_segment_t *g)
{
    double a00 = -p->rs / p->ld, a01 = omega_e * p->lq / p->ld;
    double a10 = -omega_e * p->ld / p->lq, a11 = -p->rs / p->lq;
    double det = a00 * a11 - a01 * a10;
    double c1 = -omega_e * p->psi_f / p->lq; /* back-EMF input on the q axis [A/s] */
    double vmag = hypot(v_alpha, v_beta);
    double complex w0 = vmag / p->ld, w1 = PL_J * (vmag / p->lq);
    double complex b00 = PL_J * omega_e - a00, b01 = -a01, b10 = -a10, b11 = PL_J * omega_e - a11;
    double complex bdet = b00 * b11 - b01 * b10;
    double complex e;

    g->m = 0.5 * (a00 + a11);
    g->M00 = a00 - g->m;
    g->M01 = a01;
    g->M10 = a10;
    g->M11 = a11 - g->m;
    g->delta = g->M00 * g->M00 + g->M01 * g->M10;
    /* A x0 + (0, c1) = 0 */
    g->x0_const[0] = -(-a01 * c1) / det;
    g->x0_const[1] = -(a00 * c1) / det;
    /* (j w I - A) z = w with the input written as Re(w exp(j (a0 + w t))) */
    g->z[0] = (b11 * w0 - b01 * w1) / bdet;
    g->z[1] = (b00 * w1 - b10 * w0) / bdet;
    g->a0 = theta0 - atan2(v_beta, v_alpha);
    g->omega_e = omega_e;
    e = cexp(PL_J * g->a0);
    g->h0[0] = i_d0 - (g->x0_const[0] + creal(g->z[0] * e));
    g->h0[1] = i_q0 - (g->x0_const[1] + creal(g->z[1] * e));
}

static void segment_eval(const pl_segment_t *g, double tau, double *i_d, double *i_q)
{
    double c, s, em = exp(g->m * tau);
    double dt2 = g->delta * tau * tau;
    double complex e = cexp(PL_J * (g->a0 + g->omega_e * tau));
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

typedef struct {
    double t;     /* absolute time [s] */
    int32_t leg;
    int32_t kind; /* 0: gate edge to level `level`, 1: end of dead time */
    int32_t level;
} pl_event_t;

static int add_event(pl_event_t *ev, int n, double t, int leg, int kind, int level)
{
    int k = n;
    if (n >= PL_MAX_EVENTS) {
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

static double phase_current(const pl_state_t *s, int leg)
{
    double ia, ib, ic;
    pl_phase_currents(s->i_d, s->i_q, s->theta_e, &ia, &ib, &ic);
    return leg == 0 ? ia : (leg == 1 ? ib : ic);
}

/* Integrate from the state's time over h seconds with constant leg levels; writes trace rows. */
static int integrate(const pl_params_t *p, pl_state_t *s, double t_abs, double h, int levels, double t_load0,
                     double t_load_slope, double t_period0, double trace_dt, double *trace, int32_t trace_cap,
                     pl_period_stats_t *stats)
{
    double v_alpha, v_beta;
    double done = 0.0;
    leg_voltage(p->vdc, levels, &v_alpha, &v_beta);
    while (done < h) {
        double piece = h - done;
        double omega_e = (double)p->pole_pairs * s->omega_m;
        double t0 = t_abs + done;
        pl_segment_t g;
        double i_d1, i_q1;
        if (p->inertia_mode && p->max_piece > 0.0 && piece > p->max_piece) {
            piece = p->max_piece;
        }
        segment_setup(p, omega_e, s->theta_e, v_alpha, v_beta, s->i_d, s->i_q, &g);
        if (trace_dt > 0.0 && trace != NULL) {
            for (;;) {
                double tk = (double)s->trace_k * trace_dt;
                double tau = tk - t0;
                double id, iq, th, ia, ib, ic;
                double *row;
                if (tau >= piece - 0.5e-9) { /* grid and edges are ns-aligned */
                    break;
                }
                if (stats->trace_n >= trace_cap) {
                    return PL_E_TRACE_FULL;
                }
                if (tau < 0.0) {
                    tau = 0.0;
                }
                segment_eval(&g, tau, &id, &iq);
                th = s->theta_e + omega_e * tau;
                pl_phase_currents(id, iq, th, &ia, &ib, &ic);
                row = trace + (ptrdiff_t)stats->trace_n * PL_TRACE_COLUMNS;
                row[0] = tk;
                row[1] = ia;
                row[2] = ib;
                row[3] = ic;
                row[4] = pl_torque(p, id, iq);
                row[5] = s->omega_m;
                stats->trace_n++;
                s->trace_k++;
            }
        }
        segment_eval(&g, piece, &i_d1, &i_q1);
        if (p->inertia_mode) {
            double te0 = pl_torque(p, s->i_d, s->i_q), te1 = pl_torque(p, i_d1, i_q1);
            double t_mid = t0 + 0.5 * piece - t_period0;
            double t_load = t_load0 + t_load_slope * t_mid;
            double k = 0.5 * piece * p->b / p->j;
            double w1 = (s->omega_m * (1.0 - k) + piece * (0.5 * (te0 + te1) - t_load) / p->j) / (1.0 + k);
            s->theta_e = wrap_angle(s->theta_e + omega_e * piece);
            s->omega_m = w1;
        } else {
            s->theta_e = wrap_angle(s->theta_e + omega_e * piece);
        }
        s->i_d = i_d1;
        s->i_q = i_q1;
        done += piece;
    }
    return PL_OK;
}

static int current_levels(const pl_state_t *s, const int *gate_level, double t)
{
    int levels = 0;
    for (int leg = 0; leg < 3; leg++) {
        int lvl = (t < s->dead_until[leg]) ? s->dead_level[leg] : gate_level[leg];
        levels |= lvl << (2 - leg);
    }
    return levels;
}

int pl_advance(const pl_params_t *p, pl_state_t *s, const int32_t *states, const int64_t *durations_ns,
               int32_t n, double t_load0, double t_load_slope, double trace_dt, double *trace,
               int32_t trace_cap, pl_period_stats_t *stats)
{
    pl_event_t ev[PL_MAX_EVENTS];
    int n_ev = 0;
    int gate_level[3];
    double edge_t[3][2 * PL_MAX_SUBINTERVALS + 2];
    int edge_lvl[3][2 * PL_MAX_SUBINTERVALS + 2];
    int n_edge[3] = {0, 0, 0};
    double t_start = (double)s->t_ns * 1e-9;
    int64_t total_ns = 0;
    double t_lim = 2.0 * p->t_dead + p->t_mpw;

    stats->leg_transitions = 0;
    stats->boundary_transitions = 0;
    stats->narrow_pulses = 0;
    stats->suppressed_pulses = 0;
    stats->trace_n = 0;
    stats->error = PL_OK;
    if (n < 1 || n > PL_MAX_SUBINTERVALS) {
        stats->error = PL_E_ARGS;
        return PL_E_ARGS;
    }
    for (int k = 0; k < n; k++) {
        if (durations_ns[k] < 0 || states[k] < 0 || states[k] > 7) {
            stats->error = PL_E_ARGS;
            return PL_E_ARGS;
        }
    }
    /* Commanded gate edges per leg, then minimum-pulse-width suppression (stack of edges). */
    {
        int prev = s->gate;
        int64_t acc = 0;
        for (int k = 0; k < n; k++) {
            int st = states[k];
            if (durations_ns[k] == 0) {
                continue;
            }
            for (int leg = 0; leg < 3; leg++) {
                int bit = 2 - leg;
                int old_l = (prev >> bit) & 1, new_l = (st >> bit) & 1;
                if (old_l != new_l) {
                    double te = t_start + (double)acc * 1e-9;
                    double prev_edge = n_edge[leg] > 0 ? edge_t[leg][n_edge[leg] - 1] : s->last_edge_t[leg];
                    double width = te - prev_edge;
                    if (width < t_lim) {
                        stats->narrow_pulses++;
                    }
                    if (n_edge[leg] > 0 && width < p->t_mpw) {
                        n_edge[leg]--; /* the pulse never reaches the gate: drop both edges */
                        stats->suppressed_pulses++;
                    } else {
                        edge_t[leg][n_edge[leg]] = te;
                        edge_lvl[leg][n_edge[leg]] = new_l;
                        n_edge[leg]++;
                    }
                }
            }
            prev = st;
            acc += durations_ns[k];
        }
        total_ns = acc;
    }
    for (int leg = 0; leg < 3; leg++) {
        gate_level[leg] = (s->gate >> (2 - leg)) & 1;
        for (int e = 0; e < n_edge[leg]; e++) {
            n_ev = add_event(ev, n_ev, edge_t[leg][e], leg, 0, edge_lvl[leg][e]);
            stats->leg_transitions++;
            if (edge_t[leg][e] == t_start) {
                stats->boundary_transitions++;
            }
            s->last_edge_t[leg] = edge_t[leg][e];
        }
    }
    /* Event loop: integrate between breakpoints with constant leg levels. */
    {
        double t_end = t_start + (double)total_ns * 1e-9;
        double t = t_start;
        int gate = s->gate;
        for (int leg = 0; leg < 3; leg++) {
            if (s->dead_until[leg] > t && s->dead_until[leg] < t_end) {
                n_ev = add_event(ev, n_ev, s->dead_until[leg], leg, 1, 0);
            }
        }
        for (int k = 0; k <= n_ev; k++) {
            double t_next = (k < n_ev) ? ev[k].t : t_end;
            if (t_next > t) {
                int rc = integrate(p, s, t, t_next - t, current_levels(s, gate_level, t), t_load0, t_load_slope,
                                   t_start, trace_dt, trace, trace_cap, stats);
                if (rc != PL_OK) {
                    stats->error = rc;
                    return rc;
                }
                t = t_next;
            }
            if (k == n_ev) {
                break;
            }
            if (ev[k].kind == 0) {
                int leg = ev[k].leg;
                int bit = 2 - leg;
                if (p->t_dead > 0.0) {
                    double i_x = phase_current(s, leg);
                    int lvl;
                    if (i_x > 0.0) {
                        lvl = 0; /* current out of the leg: lower diode, negative rail */
                    } else if (i_x < 0.0) {
                        lvl = 1; /* current into the leg: upper diode, positive rail */
                    } else {
                        lvl = ev[k].level; /* no current: no dead-time error (open phase not modelled) */
                    }
                    s->dead_level[leg] = lvl;
                    s->dead_until[leg] = ev[k].t + p->t_dead;
                    if (s->dead_until[leg] < t_end) {
                        n_ev = add_event(ev, n_ev, s->dead_until[leg], leg, 1, 0);
                    }
                }
                gate_level[leg] = ev[k].level;
                gate = (gate & ~(1 << bit)) | (ev[k].level << bit);
            }
        }
        s->gate = gate;
    }
    s->t_ns += (uint64_t)total_ns;
    return PL_OK;
}
