/*
 * Gate edges of one control period, shared by the plant kernels: the commanded switching sequence is
 * turned into per-leg edges, pulses shorter than t_mpw are removed before the gate, narrow pulses
 * (shorter than t_lim = 2 t_dead + t_mpw) are counted, and the surviving edges become time-ordered events.
 */
#ifndef HIL_GATE_EDGES_H
#define HIL_GATE_EDGES_H

#include <math.h>
#include <stddef.h>
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
static inline void ge_stats_reset(ge_period_stats_t *stats)
{
    stats->leg_transitions = 0;
    stats->boundary_transitions = 0;
    stats->narrow_pulses = 0;
    stats->suppressed_pulses = 0;
    stats->open_phase_events = 0;
    stats->narrow_pulses_gated = 0;
    stats->peak_current = 0.0;
    stats->trace_n = 0;
    stats->error = 0;
}

/* The next trace row of the period (row stats->trace_n of `trace`, `columns` doubles each), or NULL when `trace`
 * holds `trace_cap` rows already (the kernel's MK_E_TRACE_FULL). Inline: it runs once per trace row. */
static inline double *ge_trace_row(double *trace, int32_t trace_cap, int32_t columns,
                                   const ge_period_stats_t *stats)
{
    return stats->trace_n >= trace_cap ? NULL : trace + (ptrdiff_t)stats->trace_n * columns;
}

/* A trace row written: its `legs` phase currents `i` [A] count in the period's peak, the period's rows and the
 * kernel's trace sample index (*trace_k) move on. Returns 0. Inline: it runs once per trace row. */
static inline int ge_trace_done(ge_period_stats_t *stats, uint64_t *trace_k, const double *i, int legs)
{
    for (int k = 0; k < legs; k++) {
        if (fabs(i[k]) > stats->peak_current) {
            stats->peak_current = fabs(i[k]);
        }
    }
    stats->trace_n++;
    (*trace_k)++;
    return 0;
}

/* A period refused before it ran: the counters zeroed, the error (a negative kernel code) in stats->error and
 * returned. */
int ge_reject(ge_period_stats_t *stats, int32_t error);

/* Plan the period: `legs` legs (bit legs-1-leg of a state code is leg `leg`), applied gate code `gate`,
 * n sub-intervals (states, durations [ns]) from absolute time t_start [s]. Adds one event (kind 0) per
 * surviving edge to ev (count n_ev, capacity cap) and returns the new count; updates last_edge_t [s]
 * per leg; writes the period's total duration [ns]. */
int ge_plan(int legs, int32_t gate, const int32_t *states, const int64_t *durations_ns, int32_t n, double t_start,
            double t_mpw, double t_lim, double *last_edge_t, dq_event_t *ev, int n_ev, int cap, ge_period_stats_t *counts,
            int64_t *total_ns);

/* The per-leg gate state a gate-driven kernel keeps in its state struct (as `legs`, beside its applied gate code
 * `gate`): legs past the kernel's own are unused. */
typedef struct {
    double last_edge_t[GE_MAX_LEGS]; /* time of the last gate edge per leg [s] (absolute) */
    double dead_until[GE_MAX_LEGS];  /* leg in dead time until this absolute time [s] */
    int32_t dead_level[GE_MAX_LEGS]; /* leg level during its dead time (0: low rail, 1: high rail, or the kernel's
                                      * open level: diode blocked, phase open) */
} ge_legs_t;

/* The head of every gate-driven kernel's run context (its first member): the drive's mechanics (the kernel's params'
 * and state's `mech`), the trace destination and period stats of its advance call (see plant.h pl_advance), and the
 * gate levels per leg of the interval being integrated (set by ge_run_period). */
typedef struct {
    const mech_params_t *mech_p;
    mech_state_t *mech_s;
    double trace_dt;   /* trace row spacing [s]; <= 0: no trace */
    double *trace;     /* trace rows */
    int32_t trace_cap; /* rows `trace` holds */
    ge_period_stats_t *stats;
    int gate_level[GE_MAX_LEGS];
} ge_run_t;

/* A run context's head for one advance call. */
void ge_run_init(ge_run_t *run, const mech_params_t *mech_p, mech_state_t *mech_s, double trace_dt, double *trace,
                 int32_t trace_cap, ge_period_stats_t *stats);

/* The legs' levels at a time t0 [s] inside an interval: the gate's, or during a leg's dead time (t0 before its
 * gl->dead_until [s], less 0.5 ns) its diode's (gl->dead_level), where a leg whose dead-time level is `open_level`
 * floats. */
typedef struct {
    int level[GE_MAX_LEGS]; /* per leg: 0 low rail, 1 high rail (0 for a floating leg) */
    int code;               /* the levels as a state code, leg 0 in the highest bit */
    int cond_mask;          /* bit `leg` set: the leg conducts through a diode (in dead time, not open) */
    int n_open;             /* floating legs */
    int open_leg;           /* the last floating leg, or -1 */
} ge_levels_t;

static inline void ge_levels_at(const ge_run_t *run, int legs, double t0, const ge_legs_t *gl, int32_t open_level,
                                ge_levels_t *out)
{
    const double *dead_until = gl->dead_until;
    const int32_t *dead_level = gl->dead_level;
    out->code = 0;
    out->cond_mask = 0;
    out->n_open = 0;
    out->open_leg = -1;
    for (int leg = 0; leg < legs; leg++) {
        int lvl = run->gate_level[leg];
        if (t0 < dead_until[leg] - 0.5e-9) {
            lvl = dead_level[leg];
            if (lvl == open_level) {
                out->n_open++;
                out->open_leg = leg;
                lvl = 0;
            } else {
                out->cond_mask |= 1 << leg;
            }
        }
        out->level[leg] = lvl;
        out->code |= lvl << (legs - 1 - leg);
    }
}

/* Phase current [A] of `leg` in the kernel's state now (out of the leg > 0): what picks the dead-time diode. */
typedef double (*ge_leg_current_fn)(const void *ctx, int leg);

/* The level of a leg in dead time is the conducting diode's: current out of the leg -> lower diode (level 0, low
 * rail), into it -> upper diode (level 1, high rail); no current -> `zero_level`, or the new gate level when that is
 * GE_LEVEL_NEW. */
#define GE_LEVEL_NEW (-1)

/* A gate-driven kernel as ge_advance sees it: its legs, largest state code and most sub-intervals of a period, the
 * event capacity of a period (<= GE_MAX_EVENTS), its constant-speed piece and torque functions (mech_integrate cuts
 * each interval of constant gate levels into pieces), its leg currents and the dead-time level at zero current.
 * The run context handed to ge_advance starts with a ge_run_t. */
typedef struct {
    int legs;
    int32_t max_state;
    int32_t max_subintervals;
    int max_events;
    mech_piece_fn piece;
    mech_torque_fn torque;
    ge_leg_current_fn leg_current;
    int zero_level;
} ge_kind_t;

/* Run the period's events (gate edges from ge_plan, dead-time ends, the load's breakpoints) of a kernel of kind `k`
 * from t_start to t_end [s], integrating between them (mech_integrate with the kind's piece and torque functions on
 * the mechanics of the run context `ctx`, a ge_run_t first). Updates the applied gate code and the per-leg dead-time
 * state; returns 0 or the integrator's error. */
int ge_run_period(const ge_kind_t *k, double t_start, double t_end, double t_dead, dq_event_t *ev, int n_ev,
                  const mech_load_t *load, int32_t *gate, double *dead_until, int32_t *dead_level, void *ctx);

#define GE_MAX_EVENTS 128

/* Phase current [A] of `leg` `tau` seconds into a piece, from the kernel's closed form over it (ctx). */
typedef double (*ge_current_at_fn)(const void *ctx, double tau, int leg);

/* The earliest time in (0, piece] [s] at which the current of a leg conducting through its diode (bit `leg` of
 * cond_mask; dead_level 0: the lower diode, current out of the leg > 0) reaches zero: 8 equal steps, then bisection
 * to 1e-13 s; `piece` when none does. *leg_out is that leg, or -1. */
double ge_first_blocking(ge_current_at_fn current_at, const void *ctx, int legs, double piece, int cond_mask,
                         const int32_t *dead_level, int *leg_out);

/* One control period of a kernel of kind `k` (the whole of a kernel's *_advance but its own parameter checks and
 * run context `ctx`): stats reset; the Command (n sub-intervals of states, durations [ns]) checked, else MK_E_ARGS;
 * its gate edges planned (ge_plan, t_lim = 2 t_dead + t_mpw) and run (ge_run_period) from the plant time *t_ns,
 * which then advances by the period. The gate state (applied code `gate`, the legs' `gl`) is the kernel state's.
 * Returns 0 or the error (also in stats->error). */
int ge_advance(const ge_kind_t *k, void *ctx, const int32_t *states, const int64_t *durations_ns, int32_t n,
               const mech_load_t *load, double t_mpw, double t_dead, uint64_t *t_ns, int32_t *gate, ge_legs_t *gl,
               ge_period_stats_t *stats);

#endif
