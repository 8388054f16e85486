/* Gate edges of one control period; see gate_edges.h. */
#include "gate_edges.h"

int ge_plan(int legs, int32_t gate, const int32_t *states, const int64_t *durations_ns, int32_t n, double t_start,
            double t_mpw, double t_lim, double *last_edge_t, dq_event_t *ev, int n_ev, int cap, ge_counts_t *counts,
            int64_t *total_ns)
{
    double edge_t[GE_MAX_LEGS][GE_MAX_SUBINTERVALS + 2];
    int edge_lvl[GE_MAX_LEGS][GE_MAX_SUBINTERVALS + 2];
    int n_edge[GE_MAX_LEGS] = {0};
    int32_t prev = gate;
    int64_t acc = 0;

    counts->leg_transitions = 0;
    counts->boundary_transitions = 0;
    counts->narrow_pulses = 0;
    counts->suppressed_pulses = 0;
    counts->narrow_pulses_gated = 0;
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
