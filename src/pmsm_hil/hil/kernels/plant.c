/* Exact PMSM + two-level inverter plant kernel; see plant.h. */
#include "plant.h"
#include "dq_segment.h"
#include "gate_edges.h"
#include "mechanics.h"

#include <math.h>
#include <stddef.h>

#define PL_SQRT3 1.7320508075688772935274463415059
#define PL_MAX_EVENTS 64

double pl_torque(const pl_params_t *p, double i_d, double i_q)
{
    return 1.5 * (double)p->pole_pairs * (p->psi_f * i_q + (p->ld - p->lq) * i_d * i_q);
}

/* Phase currents [A] from the dq currents and cos, sin of the rotor angle. */
static void phase_currents_cs(double i_d, double i_q, double c, double s, double *i_a, double *i_b, double *i_c)
{
    double i_alpha = i_d * c - i_q * s;
    double i_beta = i_d * s + i_q * c;
    *i_a = i_alpha;
    *i_b = -0.5 * i_alpha + 0.5 * PL_SQRT3 * i_beta;
    *i_c = -0.5 * i_alpha - 0.5 * PL_SQRT3 * i_beta;
}

void pl_phase_currents(double i_d, double i_q, double theta_e, double *i_a, double *i_b, double *i_c)
{
    double c, s;
    dq_sincos(theta_e, &s, &c);
    phase_currents_cs(i_d, i_q, c, s, i_a, i_b, i_c);
}

/* Stator-frame voltage [V] of leg levels (bit 2: a, bit 1: b, bit 0: c). */
static void leg_voltage(double vdc, int levels, double *v_alpha, double *v_beta)
{
    double sa = (double)((levels >> 2) & 1), sb = (double)((levels >> 1) & 1), sc = (double)(levels & 1);
    *v_alpha = vdc / 3.0 * (2.0 * sa - sb - sc);
    *v_beta = vdc / PL_SQRT3 * (sb - sc);
}

static double phase_current(const pl_state_t *s, int leg)
{
    double ia, ib, ic;
    pl_phase_currents(s->i_d, s->i_q, s->theta_e, &ia, &ib, &ic);
    return leg == 0 ? ia : (leg == 1 ? ib : ic);
}

#define PL_LEVEL_OPEN 2     /* dead_level value: diode blocked, phase open */
#define PL_OPEN_STEP 25e-9  /* RK4 step while a phase is open [s] */

static const double PL_EX[3] = {1.0, -0.5, -0.5};
static const double PL_EY[3] = {0.0, 0.8660254037844386, -0.8660254037844386};

/* One trace row at time tk [s]: dq currents [A] and cos, sin of the rotor angle. */
static int emit_row_cs(const pl_params_t *p, pl_state_t *s, double tk, double i_d, double i_q, double cos_th,
                       double sin_th, double *trace, int32_t trace_cap, pl_period_stats_t *stats)
{
    double *row = ge_trace_row(trace, trace_cap, PL_TRACE_COLUMNS, stats);
    if (row == NULL) {
        return PL_E_TRACE_FULL;
    }
    row[0] = tk;
    phase_currents_cs(i_d, i_q, cos_th, sin_th, &row[1], &row[2], &row[3]);
    row[4] = pl_torque(p, i_d, i_q);
    row[5] = s->mech.omega_m;
    return ge_trace_done(stats, &s->trace_k, row + 1, 3);
}

static int emit_row(const pl_params_t *p, pl_state_t *s, double tk, double i_d, double i_q, double theta,
                    double *trace, int32_t trace_cap, pl_period_stats_t *stats)
{
    double c, sn;
    dq_sincos(theta, &sn, &c);
    return emit_row_cs(p, s, tk, i_d, i_q, c, sn, trace, trace_cap, stats);
}

static double leg_current(double i_d, double i_q, double theta, int leg)
{
    double ia, ib, ic;
    pl_phase_currents(i_d, i_q, theta, &ia, &ib, &ic);
    return leg == 0 ? ia : (leg == 1 ? ib : ic);
}

/* Rotor-frame direction h = R(-theta) (e_y - e_z) of the current loop through phases y -> z. */
static void loop_direction(int y, int z, double theta, double *h_d, double *h_q)
{
    double dx = PL_EX[y] - PL_EX[z], dy = PL_EY[y] - PL_EY[z];
    double c, sn;
    dq_sincos(theta, &sn, &c);
    *h_d = c * dx + sn * dy;
    *h_q = -sn * dx + c * dy;
}

/* d i / dt of the loop current i (into phase y, out of phase z) with the third phase open. */
static double open_didt(const pl_params_t *p, int y, int z, double v_yz, double omega_e, double theta, double i)
{
    double h_d, h_q;
    double psi_d, psi_q, hlh, hljh, hjpsi;
    loop_direction(y, z, theta, &h_d, &h_q);
    psi_d = p->ld * (2.0 / 3.0) * h_d * i + p->psi_f;
    psi_q = p->lq * (2.0 / 3.0) * h_q * i;
    hlh = p->ld * h_d * h_d + p->lq * h_q * h_q;
    hljh = h_d * (-p->ld * h_q) + h_q * (p->lq * h_d); /* h . L J h */
    hjpsi = h_d * (-psi_q) + h_q * psi_d;               /* h . J psi */
    return (v_yz - 2.0 * p->rs * i + (2.0 / 3.0) * omega_e * i * hljh - omega_e * hjpsi) / ((2.0 / 3.0) * hlh);
}

/* One phase open: integrate the loop current of the two connected phases by RK4 (steps <= 25 ns). */
static int integrate_open(const pl_params_t *p, pl_state_t *s, double t0, double piece, double omega_e, int levels,
                          int open_leg, int cond_mask, double trace_dt, double *trace, int32_t trace_cap,
                          pl_period_stats_t *stats, int *newly_open)
{
    int y = (open_leg + 1) % 3, z = (open_leg + 2) % 3;
    double v_yz = p->vdc * (double)(((levels >> (2 - y)) & 1) - ((levels >> (2 - z)) & 1));
    double theta = s->theta_e, tau = 0.0, h_d, h_q, i;
    loop_direction(y, z, theta, &h_d, &h_q);
    i = 0.5 * (h_d * s->i_d + h_q * s->i_q); /* project onto the loop (|h|^2 = 3) */
    *newly_open = -1;
    while (tau < piece - 0.5e-9) {
        double stop = piece, hstep, k1, k2, k3, k4;
        int n_sub;
        if (trace_dt > 0.0 && trace != NULL) {
            double tk = (double)s->trace_k * trace_dt;
            if (tk - (t0 + tau) < 0.5e-9) {
                int rc;
                loop_direction(y, z, theta, &h_d, &h_q);
                rc = emit_row(p, s, tk, (2.0 / 3.0) * h_d * i, (2.0 / 3.0) * h_q * i, theta, trace, trace_cap, stats);
                if (rc != PL_OK) {
                    return rc;
                }
                tk = (double)s->trace_k * trace_dt;
            }
            if (tk - t0 < stop) {
                stop = tk - t0;
            }
        }
        n_sub = (int)ceil((stop - tau) / PL_OPEN_STEP - 1e-9);
        if (n_sub < 1) {
            n_sub = 1;
        }
        hstep = (stop - tau) / (double)n_sub;
        for (int k = 0; k < n_sub; k++) {
            double i_prev = i;
            k1 = open_didt(p, y, z, v_yz, omega_e, theta, i);
            k2 = open_didt(p, y, z, v_yz, omega_e, theta + 0.5 * omega_e * hstep, i + 0.5 * hstep * k1);
            k3 = open_didt(p, y, z, v_yz, omega_e, theta + 0.5 * omega_e * hstep, i + 0.5 * hstep * k2);
            k4 = open_didt(p, y, z, v_yz, omega_e, theta + omega_e * hstep, i + hstep * k3);
            i += hstep / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
            theta += omega_e * hstep;
            /* a connected leg conducting through its diode blocks when its current crosses zero */
            if ((i_prev > 0.0 && i <= 0.0) || (i_prev < 0.0 && i >= 0.0)) {
                int leg_y_cond = (cond_mask >> y) & 1, leg_z_cond = (cond_mask >> z) & 1;
                if (leg_y_cond || leg_z_cond) {
                    i = 0.0;
                    *newly_open = leg_y_cond ? y : z;
                }
            }
        }
        tau = stop;
    }
    loop_direction(y, z, theta, &h_d, &h_q);
    s->i_d = (2.0 / 3.0) * h_d * i;
    s->i_q = (2.0 / 3.0) * h_q * i;
    s->theta_e = dq_wrap_angle(theta);
    return PL_OK;
}

/* The closed form of one piece as ge_first_blocking reads it: the segment, the rotor angle at its start [rad] and
 * the electrical speed [rad/s]. */
typedef struct {
    const dq_segment_t *g;
    double theta0, omega_e;
} pl_piece_form_t;

static double pl_current_at(const void *ctx, double tau, int leg)
{
    const pl_piece_form_t *f = (const pl_piece_form_t *)ctx;
    double id, iq;
    dq_segment_eval(f->g, tau, &id, &iq);
    return leg_current(id, iq, f->theta0 + f->omega_e * tau, leg);
}

/* One interval of constant gate levels (gate_edges.c) as the mechanics cuts it into constant-speed pieces
 * (mechanics.h): the kernel's part of the state, the trace and the machine's closed-form constants. */
typedef struct {
    ge_run_t run;          /* the mechanics, the trace, the stats, the gate levels (gate_edges.h) */
    const pl_params_t *p;
    pl_state_t *s;
    dq_machine_t mc;       /* the closed-form constants of the machine */
    double em_step;        /* exp(m trace_dt) of the trace walker */
} pl_run_ctx_t;

static double pl_torque_cb(const void *ctx)
{
    const pl_run_ctx_t *c = (const pl_run_ctx_t *)ctx;
    return pl_torque(c->p, c->s->i_d, c->s->i_q);
}

/* One piece from absolute time t0 [s] at the constant speed omega_m [rad/s] (open legs float); legs in dead time
 * conduct through a diode until their current reaches zero (the piece then ends there), then open. */
static int pl_piece_cb(void *ctx, double t0, double *piece_io, double omega_m)
{
    pl_run_ctx_t *c = (pl_run_ctx_t *)ctx;
    const pl_params_t *p = c->p;
    pl_state_t *s = c->s;
    const double trace_dt = c->run.trace_dt;
    double *trace = c->run.trace;
    const int32_t trace_cap = c->run.trace_cap;
    pl_period_stats_t *stats = c->run.stats;
    double piece = *piece_io;
    const double omega_e = (double)p->pole_pairs * omega_m;
    int blocked = -1;
    ge_levels_t lv;
    ge_levels_at(&c->run, 3, t0, &s->legs, PL_LEVEL_OPEN, &lv);
    if (lv.n_open == 0) {
        dq_segment_t g;
        double v_alpha, v_beta, i_d1, i_q1;
        leg_voltage(p->vdc, lv.code, &v_alpha, &v_beta);
        dq_segment_setup(&c->mc, omega_e, s->theta_e, v_alpha, v_beta, s->i_d, s->i_q, &g);
        if (lv.cond_mask) {
            const pl_piece_form_t form = {&g, s->theta_e, omega_e};
            piece = ge_first_blocking(pl_current_at, &form, 3, piece, lv.cond_mask, s->legs.dead_level, &blocked);
        }
        if (trace_dt > 0.0 && trace != NULL) {
            dq_walk_t w;
            int fresh = 1;
            for (;;) {
                double tk = (double)s->trace_k * trace_dt;
                double tau = tk - t0, id, iq;
                int rc, clamped = 0;
                if (tau >= piece - 0.5e-9) { /* grid and edges are ns-aligned */
                    break;
                }
                if (tau < 0.0) {
                    tau = 0.0;
                    clamped = 1;
                }
                if (fresh) {
                    dq_walk_start(&g, tau, trace_dt, c->em_step, &w);
                }
                dq_walk_eval(&g, &w, &id, &iq);
                rc = emit_row_cs(p, s, tk, id, iq, w.cos_th, w.sin_th, trace, trace_cap, stats);
                if (rc != PL_OK) {
                    return rc;
                }
                fresh = clamped || !dq_walk_next(&g, &w);
            }
        }
        dq_segment_eval(&g, piece, &i_d1, &i_q1);
        s->theta_e = dq_wrap_angle(s->theta_e + omega_e * piece);
        s->i_d = i_d1;
        s->i_q = i_q1;
    } else if (lv.n_open == 1) {
        int rc = integrate_open(p, s, t0, piece, omega_e, lv.code, lv.open_leg, lv.cond_mask, trace_dt, trace,
                                trace_cap, stats, &blocked);
        if (rc != PL_OK) {
            return rc;
        }
    } else {
        /* two or three phases open: no current can flow */
        s->i_d = 0.0;
        s->i_q = 0.0;
        while (trace_dt > 0.0 && trace != NULL) {
            double tk = (double)s->trace_k * trace_dt;
            int rc;
            if (tk - t0 >= piece - 0.5e-9) {
                break;
            }
            rc = emit_row(p, s, tk, 0.0, 0.0, s->theta_e + omega_e * (tk - t0 > 0.0 ? tk - t0 : 0.0), trace,
                          trace_cap, stats);
            if (rc != PL_OK) {
                return rc;
            }
        }
        s->theta_e = dq_wrap_angle(s->theta_e + omega_e * piece);
    }
    if (blocked >= 0) {
        s->legs.dead_level[blocked] = PL_LEVEL_OPEN;
        stats->open_phase_events++;
    }
    *piece_io = piece;
    return PL_OK;
}

/* Diode by the current's sign; no current -> no diode conducts and the phase is open (gate_edges.h). */
static double pl_leg_current_cb(const void *ctx, int leg)
{
    return phase_current(((const pl_run_ctx_t *)ctx)->s, leg);
}

static const ge_kind_t PL_GATES = {3, 7, PL_MAX_SUBINTERVALS, PL_MAX_EVENTS, pl_piece_cb, pl_torque_cb,
                                   pl_leg_current_cb, PL_LEVEL_OPEN};

int pl_advance(const pl_params_t *p, pl_state_t *s, const int32_t *states, const int64_t *durations_ns,
               int32_t n, const mech_load_t *load, double trace_dt, double *trace, int32_t trace_cap,
               pl_period_stats_t *stats)
{
    pl_run_ctx_t c;
    ge_run_init(&c.run, &p->mech, &s->mech, trace_dt, trace, trace_cap, stats);
    c.p = p;
    c.s = s;
    dq_machine_init(p->rs, p->ld, p->lq, p->psi_f, &c.mc);
    c.em_step = trace_dt > 0.0 ? exp(c.mc.m * trace_dt) : 1.0;
    return ge_advance(&PL_GATES, &c, states, durations_ns, n, load, p->t_mpw, p->t_dead, &s->t_ns, &s->gate,
                      &s->legs, stats);
}

/* Plant.sample (src/pmsm_hil/hil/plant.py) with the same expressions, so the native loop's records equal the Python
 * loop's bit for bit: inverse Park with cos/sin of the angle, Clarke with sqrt(3)/2, torque
 * 1.5*p*(psi_f + (Ld - Lq)*i_d)*i_q. */
static void pl_sample(const pl_params_t *p, const pl_state_t *s, mk_sample_t *out)
{
    const double i_d = s->i_d;
    const double i_q = s->i_q;
    const double co = cos(s->theta_e);
    const double sn = sin(s->theta_e);
    const double i_al = i_d * co - i_q * sn;
    const double i_be = i_d * sn + i_q * co;
    const double sqrt3_2 = 0.5 * PL_SQRT3;
    const double torque_k = 1.5 * (double)p->pole_pairs;
    out->i[0] = i_al;
    out->i[1] = -0.5 * i_al + sqrt3_2 * i_be;
    out->i[2] = -0.5 * i_al - sqrt3_2 * i_be;
    out->i_d = i_d;
    out->i_q = i_q;
    out->theta_e = s->theta_e;
    out->omega_m = s->mech.omega_m;
    out->torque = torque_k * (p->psi_f + (p->ld - p->lq) * i_d) * i_q;
}

/* the machine-kernel table (machine_kernel.h) */
MK_KERNEL_TABLE(pl, pl_params_t, pl_state_t, pl_advance, pl_sample, "three-phase PMSM", 3, 7, PL_TRACE_COLUMNS)
