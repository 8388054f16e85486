/* Gate edges of one control period; see gate_edges.h. */
#include "gate_edges.h"

#include <math.h>
#include <stddef.h>

#include "machine_kernel.h"

int ge_plan(int legs, int32_t gate, const int32_t *states, const int64_t *durations_ns, int32_t n, double t_start,
            double t_mpw, double t_lim, double *last_edge_t, dq_event_t *ev, int n_ev, int cap, ge_period_stats_t *counts,
            int64_t *total_ns)
{
    double edge_t[GE_MAX_LEGS][GE_MAX_SUBINTERVALS + 2];
    int edge_lvl[GE_MAX_LEGS][GE_MAX_SUBINTERVALS + 2];
    int n_edge[GE_MAX_LEGS] = {0};
    int32_t prev = gate;
    int64_t acc = 0;

    for (int k = 0; k < n; k++) {
        int32_t st = states[k];
        if (durations_ns[k] == 0) {
            continue;
        }
        for (int leg = 0; leg < legs; leg++) {
            int bit = legs - 1 - leg;
            int old_l = (prev >> bit) & 1, new_l = (st >> bit) & 1;
            if (old_l != new_l) {
                double te = t_start + (double)acc * 1e-9;
                double prev_edge = n_edge[leg] > 0 ? edge_t[leg][n_edge[leg] - 1] : last_edge_t[leg];
                double width = te - prev_edge;
                if (width < t_lim) {
                    counts->narrow_pulses++;
                }
                if (n_edge[leg] > 0 && width < t_mpw) {
                    n_edge[leg]--; /* the pulse never reaches the gate: drop both edges */
                    counts->suppressed_pulses++;
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
    *total_ns = acc;
    for (int leg = 0; leg < legs; leg++) {
        for (int e = 0; e < n_edge[leg]; e++) {
            n_ev = dq_add_event(ev, n_ev, cap, edge_t[leg][e], leg, 0, edge_lvl[leg][e]);
            counts->leg_transitions++;
            if (edge_t[leg][e] - last_edge_t[leg] < t_lim) {
                counts->narrow_pulses_gated++;
            }
            if (edge_t[leg][e] == t_start) {
                counts->boundary_transitions++;
            }
            last_edge_t[leg] = edge_t[leg][e];
        }
    }
    return n_ev;
}

void ge_run_init(ge_run_t *run, const mech_params_t *mech_p, mech_state_t *mech_s, double trace_dt, double *trace,
                 int32_t trace_cap, ge_period_stats_t *stats)
{
    const ge_run_t head = {mech_p, mech_s, trace_dt, trace, trace_cap, stats, {0}};
    *run = head;
}

int ge_reject(ge_period_stats_t *stats, int32_t error)
{
    ge_stats_reset(stats);
    stats->error = error;
    return error;
}

/* The dead-time level of `leg` switching to `new_level`: the conducting diode's (gate_edges.h, GE_LEVEL_NEW). */
static int32_t dead_level_of(const ge_kind_t *k, const void *ctx, int leg, int new_level)
{
    const double i_x = k->leg_current(ctx, leg);
    return i_x > 0.0 ? 0 : (i_x < 0.0 ? 1 : (k->zero_level == GE_LEVEL_NEW ? new_level : k->zero_level));
}

int ge_run_period(const ge_kind_t *k, double t_start, double t_end, double t_dead, dq_event_t *ev, int n_ev,
                  const mech_load_t *load, int32_t *gate, double *dead_until, int32_t *dead_level, void *ctx)
{
    ge_run_t *run = (ge_run_t *)ctx;
    int *gate_level = run->gate_level;
    const int legs = k->legs;
    const int cap = k->max_events;
    double t = t_start;
    const double *load_bp = load->bp;
    const int32_t n_load_bp = load->n_bp;
    mech_segment_t seg; /* the load segment in force */
    int32_t g = *gate;
    seg.t_ref = t_start;
    seg.value = load->value;
    seg.slope = load->slope;
    for (int leg = 0; leg < legs; leg++) {
        gate_level[leg] = (g >> (legs - 1 - leg)) & 1;
        if (dead_until[leg] > t && dead_until[leg] < t_end) {
            n_ev = dq_add_event(ev, n_ev, cap, dead_until[leg], leg, 1, 0);
        }
    }
    for (int b = 0; b < n_load_bp && load_bp != NULL; b++) {
        if (load_bp[3 * b] > t_start && load_bp[3 * b] < t_end) {
            n_ev = dq_add_event(ev, n_ev, cap, load_bp[3 * b], b, 2, 0);
        }
    }
    for (int e = 0; e <= n_ev; e++) {
        double t_next = (e < n_ev) ? ev[e].t : t_end;
        if (t_next > t) {
            int rc = mech_integrate(run->mech_p, run->mech_s, &seg, t, t_next - t, k->piece, k->torque, ctx);
            if (rc != 0) {
                *gate = g;
                return rc;
            }
            t = t_next;
        }
        if (e == n_ev) {
            break;
        }
        if (ev[e].kind == 2) { /* a load-profile breakpoint inside the period */
            const double *bp = load_bp + 3 * ev[e].leg;
            seg.t_ref = bp[0];
            seg.value = bp[1];
            seg.slope = bp[2];
        } else if (ev[e].kind == 0) {
            int leg = ev[e].leg;
            int bit = legs - 1 - leg;
            if (t_dead > 0.0) {
                dead_level[leg] = dead_level_of(k, ctx, leg, ev[e].level);
                dead_until[leg] = ev[e].t + t_dead;
                if (dead_until[leg] < t_end) {
                    n_ev = dq_add_event(ev, n_ev, cap, dead_until[leg], leg, 1, 0);
                }
            }
            gate_level[leg] = ev[e].level;
            g = (g & ~(1 << bit)) | (ev[e].level << bit);
        }
    }
    *gate = g;
    return 0;
}

int ge_advance(const ge_kind_t *k, void *ctx, const int32_t *states, const int64_t *durations_ns, int32_t n,
               const mech_load_t *load, double t_mpw, double t_dead, uint64_t *t_ns, int32_t *gate, ge_legs_t *gl,
               ge_period_stats_t *stats)
{
    dq_event_t ev[GE_MAX_EVENTS];
    const double t_start = (double)*t_ns * 1e-9;
    int64_t total_ns = 0;
    int n_ev;
    int rc;
    if (n < 1 || n > k->max_subintervals) {
        return ge_reject(stats, MK_E_ARGS);
    }
    for (int i = 0; i < n; i++) {
        if (durations_ns[i] < 0 || states[i] < 0 || states[i] > k->max_state) {
            return ge_reject(stats, MK_E_ARGS);
        }
    }
    ge_stats_reset(stats);
    n_ev = ge_plan(k->legs, *gate, states, durations_ns, n, t_start, t_mpw, 2.0 * t_dead + t_mpw, gl->last_edge_t, ev,
                   0, k->max_events, stats, &total_ns);
    rc = ge_run_period(k, t_start, t_start + (double)total_ns * 1e-9, t_dead, ev, n_ev, load, gate, gl->dead_until,
                       gl->dead_level, ctx);
    if (rc != 0) {
        stats->error = rc;
        return rc;
    }
    *t_ns += (uint64_t)total_ns;
    return 0;
}

double ge_first_blocking(ge_current_at_fn current_at, const void *ctx, int legs, double piece, int cond_mask,
                         const int32_t *dead_level, int *leg_out)
{
    double best = piece;
    *leg_out = -1;
    for (int leg = 0; leg < legs; leg++) {
        double sign, lo = 0.0, hi = -1.0;
        if (!((cond_mask >> leg) & 1)) {
            continue;
        }
        sign = dead_level[leg] == 0 ? 1.0 : -1.0; /* low rail: current out of the leg (> 0) */
        for (int q = 1; q <= 8; q++) {
            const double tau = piece * (double)q / 8.0;
            if (sign * current_at(ctx, tau, leg) <= 0.0) {
                hi = tau;
                break;
            }
            lo = tau;
        }
        if (hi < 0.0) {
            continue;
        }
        for (int it = 0; it < 60 && hi - lo > 1e-13; it++) {
            const double mid = 0.5 * (lo + hi);
            if (sign * current_at(ctx, mid, leg) <= 0.0) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        if (hi < best || (*leg_out < 0 && hi <= best)) {
            best = hi;
            *leg_out = leg;
        }
    }
    return best;
}
