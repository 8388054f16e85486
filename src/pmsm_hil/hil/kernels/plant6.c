/* Exact dual three-phase PMSM + six-leg inverter plant kernel; see plant6.h.
 *
 * The dq closed form is shared with the three-phase kernel (dq_segment.c, docs/plant.md). Dead time: the sign rule per leg (the diode chosen by the
 * phase current sign at the gate edge conducts for the whole dead time); the three-phase kernel's
 * open-phase logic (diode blocking at a current zero crossing) is not modelled for six phases. */
#include "plant6.h"
#include "dq_segment.h"
#include "gate_edges.h"
#include "mechanics.h"

#include <math.h>
#include <stddef.h>

#define P6_MAX_EVENTS 128
#define P6_H3 0.86602540378443864676372317075294 /* sqrt(3)/2 */

/* Rows of the VSD matrix without its 1/3 factor: alpha, beta, x, y over phases A B C U V W. */
static const double P6_VSD[4][P6_LEGS] = {
    {1.0, -0.5, -0.5, P6_H3, -P6_H3, 0.0},
    {0.0, P6_H3, -P6_H3, 0.5, 0.5, -1.0},
    {1.0, -0.5, -0.5, -P6_H3, P6_H3, 0.0},
    {0.0, -P6_H3, P6_H3, 0.5, 0.5, -1.0},
};


double p6_torque(const p6_params_t *p, double i_d, double i_q)
{
    return 3.0 * (double)p->pole_pairs * (p->psi_f * i_q + (p->ld - p->lq) * i_d * i_q);
}

/* Phase currents [A] from the dq currents, cos and sin of the rotor angle, and the x-y currents. */
static void phase_currents_cs(double i_d, double i_q, double c, double s, double i_x, double i_y, double *i_phase)
{
    double v[4];
    v[0] = i_d * c - i_q * s;
    v[1] = i_d * s + i_q * c;
    v[2] = i_x;
    v[3] = i_y;
    for (int k = 0; k < P6_LEGS; k++) {
        i_phase[k] = P6_VSD[0][k] * v[0] + P6_VSD[1][k] * v[1] + P6_VSD[2][k] * v[2] + P6_VSD[3][k] * v[3];
    }
}

void p6_phase_currents(double i_d, double i_q, double theta_e, double i_x, double i_y, double *i_phase)
{
    double c, s;
    dq_sincos(theta_e, &s, &c);
    phase_currents_cs(i_d, i_q, c, s, i_x, i_y, i_phase);
}

void p6_code_voltage(double vdc, int32_t code, double *v4)
{
    for (int r = 0; r < 4; r++) {
        double acc = 0.0;
        for (int k = 0; k < P6_LEGS; k++) {
            acc += P6_VSD[r][k] * (double)((code >> (P6_LEGS - 1 - k)) & 1);
        }
        v4[r] = vdc / 3.0 * acc; /* per-group common mode drops out: each row sums to 0 per group */
    }
}

/* One trace row at time tk [s]: dq currents [A], cos and sin of the rotor angle, x-y currents [A]. */
static int emit_row(const p6_params_t *p, p6_state_t *s, double tk, double i_d, double i_q, double cos_th,
                    double sin_th, double i_x, double i_y, double *trace, int32_t trace_cap, p6_period_stats_t *stats)
{
    double *row = ge_trace_row(trace, trace_cap, P6_TRACE_COLUMNS, stats);
    if (row == NULL) {
        return P6_E_TRACE_FULL;
    }
    row[0] = tk;
    phase_currents_cs(i_d, i_q, cos_th, sin_th, i_x, i_y, row + 1);
    row[7] = p6_torque(p, i_d, i_q);
    row[8] = s->mech.omega_m;
    row[9] = i_x;
    row[10] = i_y;
    return ge_trace_done(stats, &s->trace_k, row + 1, P6_LEGS);
}

/* One interval of constant gate levels (gate_edges.c) as the mechanics cuts it into constant-speed pieces
 * (mechanics.h): the kernel's part of the state, the trace and the machine's closed-form constants. */
typedef struct {
    ge_run_t run;          /* the mechanics, the trace, the stats, the gate levels (gate_edges.h) */
    const p6_params_t *p;
    p6_state_t *s;
    dq_machine_t mc;       /* the closed-form constants of the dq subspace */
    double em_step;        /* exp(m trace_dt) of the trace walker */
} p6_run_ctx_t;

static double p6_torque_cb(const void *ctx)
{
    const p6_run_ctx_t *c = (const p6_run_ctx_t *)ctx;
    return p6_torque(c->p, c->s->i_d, c->s->i_q);
}

/* One piece from absolute time t0 [s] at the constant speed omega_m [rad/s] (legs in dead time at their diode
 * level). */
static int p6_piece_cb(void *ctx, double t0, double *piece_io, double omega_m)
{
    p6_run_ctx_t *c = (p6_run_ctx_t *)ctx;
    const p6_params_t *p = c->p;
    p6_state_t *s = c->s;
    const double trace_dt = c->run.trace_dt;
    double *trace = c->run.trace;
    const double piece = *piece_io;
    const double omega_e = (double)p->pole_pairs * omega_m;
    double v[4], ix_inf, iy_inf, kxy, i_d1, i_q1;
    ge_levels_t lv;
    dq_segment_t g;
    ge_levels_at(&c->run, P6_LEGS, t0, &s->legs, GE_LEVEL_NEW, &lv); /* no leg floats */
    p6_code_voltage(p->vdc, lv.code, v);
    dq_segment_setup(&c->mc, omega_e, s->theta_e, v[0], v[1], s->i_d, s->i_q, &g);
    ix_inf = v[2] / p->rs;
    iy_inf = v[3] / p->rs;
    kxy = -p->rs / p->lls;
    if (trace_dt > 0.0 && trace != NULL) {
        dq_walk_t w;
        double ex = 1.0, ex_step = exp(kxy * trace_dt);
        int fresh = 1;
        for (;;) {
            double tk = (double)s->trace_k * trace_dt;
            double tau = tk - t0, id, iq;
            int rc, clamped = 0;
            if (tau >= piece - 0.5e-9) {
                break;
            }
            if (tau < 0.0) {
                tau = 0.0;
                clamped = 1;
            }
            if (fresh) {
                dq_walk_start(&g, tau, trace_dt, c->em_step, &w);
                ex = exp(kxy * tau);
            }
            dq_walk_eval(&g, &w, &id, &iq);
            rc = emit_row(p, s, tk, id, iq, w.cos_th, w.sin_th, ix_inf + (s->i_x - ix_inf) * ex,
                          iy_inf + (s->i_y - iy_inf) * ex, trace, c->run.trace_cap, c->run.stats);
            if (rc != P6_OK) {
                return rc;
            }
            fresh = clamped || !dq_walk_next(&g, &w);
            ex *= ex_step;
        }
    }
    dq_segment_eval(&g, piece, &i_d1, &i_q1);
    {
        double ex = exp(kxy * piece);
        s->i_x = ix_inf + (s->i_x - ix_inf) * ex;
        s->i_y = iy_inf + (s->i_y - iy_inf) * ex;
    }
    s->theta_e = dq_wrap_angle(s->theta_e + omega_e * piece);
    s->i_d = i_d1;
    s->i_q = i_q1;
    return P6_OK;
}

static double phase_current(const p6_state_t *s, int leg)
{
    double ip[P6_LEGS];
    p6_phase_currents(s->i_d, s->i_q, s->theta_e, s->i_x, s->i_y, ip);
    return ip[leg];
}

/* Diode by the current's sign; exactly zero -> the new level (no open-phase model for six phases). */
static double p6_leg_current_cb(const void *ctx, int leg)
{
    return phase_current(((const p6_run_ctx_t *)ctx)->s, leg);
}

static const ge_kind_t P6_GATES = {P6_LEGS, 63, P6_MAX_SUBINTERVALS, P6_MAX_EVENTS, p6_piece_cb, p6_torque_cb,
                                   p6_leg_current_cb, GE_LEVEL_NEW};

int p6_advance(const p6_params_t *p, p6_state_t *s, const int32_t *states, const int64_t *durations_ns,
               int32_t n, const mech_load_t *load, double trace_dt, double *trace, int32_t trace_cap,
               p6_period_stats_t *stats)
{
    p6_run_ctx_t c;
    if (!(p->lls > 0.0) || !(p->rs > 0.0)) {
        return ge_reject(stats, P6_E_ARGS);
    }
    ge_run_init(&c.run, &p->mech, &s->mech, trace_dt, trace, trace_cap, stats);
    c.p = p;
    c.s = s;
    dq_machine_init(p->rs, p->ld, p->lq, p->psi_f, &c.mc);
    c.em_step = trace_dt > 0.0 ? exp(c.mc.m * trace_dt) : 1.0;
    return ge_advance(&P6_GATES, &c, states, durations_ns, n, load, p->t_mpw, p->t_dead, &s->t_ns, &s->gate,
                      &s->legs, stats);
}

/* Plant6.sample (src/pmsm_hil/hil/plant6.py): the same kernel functions. */
static void p6_sample(const p6_params_t *p, const p6_state_t *s, mk_sample_t *out)
{
    p6_phase_currents(s->i_d, s->i_q, s->theta_e, s->i_x, s->i_y, out->i);
    out->i_d = s->i_d;
    out->i_q = s->i_q;
    out->i_x = s->i_x;
    out->i_y = s->i_y;
    out->theta_e = s->theta_e;
    out->omega_m = s->mech.omega_m;
    out->torque = p6_torque(p, s->i_d, s->i_q);
}

/* the machine-kernel table (machine_kernel.h) */
MK_KERNEL_TABLE(p6, p6_params_t, p6_state_t, p6_advance, p6_sample, "dual three-phase PMSM", P6_LEGS, 63,
                P6_TRACE_COLUMNS)
