/*
 * Gate edges of one control period, shared by the plant kernels: the commanded switching sequence is
 * turned into per-leg edges, pulses shorter than t_mpw are removed before the gate, narrow pulses
 * (shorter than t_lim = 2 t_dead + t_mpw) are counted, and the surviving edges become time-ordered events.
 */
#ifndef HIL_GATE_EDGES_H
#define HIL_GATE_EDGES_H

#include <stdint.h>

#include "dq_segment.h"
#include "mechanics.h"

#define GE_MAX_LEGS 6
#define GE_MAX_SUBINTERVALS 16 /* the 13 segments of six duty cycles (pwm_duty.h) fit */

/* Statistics of one advanced period, shared by both plant kernels (pl_/p6_period_stats_t). */
typedef struct {
    uint32_t leg_transitions;      /* gate transitions that reached the legs (after T_mpw) */
    uint32_t boundary_transitions; /* of which at the period start */
    uint32_t narrow_pulses;        /* requested pulses shorter than 2*t_dead + t_mpw (counted when they end) */
    uint32_t suppressed_pulses;    /* pulses shorter than t_mpw removed before the gate */
    uint32_t open_phase_events;    /* dead-time diode currents that reached zero (three-phase kernel only) */
    uint32_t narrow_pulses_gated;  /* narrow pulses that reached the gate (not suppressed by t_mpw) */
    double peak_current;           /* largest |phase current| at the trace rows of the period [A] */
    int32_t trace_n;               /* trace rows written */
    int32_t error;                 /* 0 ok, negative: the kernel's error codes */
} ge_period_stats_t;

/* Zero every counter of a period. */
void ge_stats_reset(ge_period_stats_t *stats);

/* Plan the period: `legs` legs (bit legs-1-leg of a state code is leg `leg`), applied gate code `gate`,
 * n sub-intervals (states, durations [ns]) from absolute time t_start [s]. Adds one event (kind 0) per
 * surviving edge to ev (count n_ev, capacity cap) and returns the new count; updates last_edge_t [s]
 * per leg; writes the period's total duration [ns]. */
int ge_plan(int legs, int32_t gate, const int32_t *states, const int64_t *durations_ns, int32_t n, double t_start,
            double t_mpw, double t_lim, double *last_edge_t, dq_event_t *ev, int n_ev, int cap, ge_period_stats_t *counts,
            int64_t *total_ns);

/* Integrate h seconds from absolute time t [s] with the given leg gate levels under the load segment in force
 * (for the mechanics). Returns 0 or a kernel error code. */
typedef int (*ge_integrate_fn)(void *ctx, double t, double h, const mech_segment_t *load, const int *gate_level);
/* Leg output level during the dead time that starts now for `leg` switching to `new_level`. */
typedef int (*ge_dead_level_fn)(void *ctx, int leg, int new_level);

/* Run the period's events (gate edges from ge_plan, dead-time ends, the load's breakpoints) from t_start to t_end [s],
 * integrating between them.
 * Updates the applied gate code and the per-leg dead-time state; returns 0 or the integrator's error. */
int ge_run_period(int legs, double t_start, double t_end, double t_dead, dq_event_t *ev, int n_ev, int cap,
                  const mech_load_t *load, int32_t *gate,
                  double *dead_until, int32_t *dead_level, ge_integrate_fn integrate, ge_dead_level_fn dead_level_of,
                  void *ctx);

/* A gate-driven kernel as ge_advance sees it: its legs, largest state code and most sub-intervals of a period, the
 * event capacity of a period (<= GE_MAX_EVENTS), and how it integrates and picks a dead-time level. */
typedef struct {
    int legs;
    int32_t max_state;
    int32_t max_subintervals;
    int max_events;
    ge_integrate_fn integrate;
    ge_dead_level_fn dead_level_of;
} ge_kind_t;

#define GE_MAX_EVENTS 128

/* One control period of a kernel of kind `k` (the whole of a kernel's *_advance but its own parameter checks and
 * run context `ctx`): stats reset; the Command (n sub-intervals of states, durations [ns]) checked, else MK_E_ARGS;
 * its gate edges planned (ge_plan, t_lim = 2 t_dead + t_mpw) and run (ge_run_period) from the plant time *t_ns,
 * which then advances by the period. The gate state (applied code, per-leg last edge, dead-time end and level) is
 * the kernel state's. Returns 0 or the error (also in stats->error). */
int ge_advance(const ge_kind_t *k, void *ctx, const int32_t *states, const int64_t *durations_ns, int32_t n,
               const mech_load_t *load, double t_mpw, double t_dead, uint64_t *t_ns, int32_t *gate,
               double *last_edge_t, double *dead_until, int32_t *dead_level, ge_period_stats_t *stats);

#endif
