/*
 * The machine-kernel interface: what the native period loop (loop.c) needs of a plant, as a table of function
 * pointers. A machine kind's C file (plant.c, plant6.c, ...) defines one const table and a function returning
 * its address; the Python plant class hands that address, with its own params and state structs, to the loop.
 * The loop calls only through the table: it never knows the machine type, its parameters or its state layout.
 * A kernel is its electrical model: its params and state structs hold the drive's mechanics (mechanics.h), and
 * mech_integrate moves the speed between the kernel's constant-speed pieces; the load reaches only the mechanics.
 *
 * Units: SI (A, rad electrical, rad/s mechanical, N*m, s); plant time in ns.
 */
#ifndef HIL_MACHINE_KERNEL_H
#define HIL_MACHINE_KERNEL_H

#include <stdint.h>

#include "gate_edges.h"
#include "mechanics.h"

/* Bumped whenever mk_kernel_t or mk_sample_t changes; the loop refuses a table of another version. */
#define MK_ABI_VERSION 2
/* Kernel error codes every kernel uses (its own codes are other negative values). */
#define MK_E_ARGS (-1)       /* bad arguments (state code, durations, n) */
#define MK_E_TRACE_FULL (-2) /* more trace rows than trace_cap */

/* Most inverter legs (measured phase currents) a kernel may have. */
#define MK_MAX_LEGS 6

/* The plant's exact state at a period start. The loop fills every field with NaN first; a kernel writes what
 * its machine has (i[0..legs-1], and i_x, i_y only with a second winding set). */
typedef struct {
    double i[MK_MAX_LEGS];      /* phase currents [A], in the order of the inverter legs */
    double i_d, i_q;            /* torque-producing current components, rotor frame [A] */
    double i_x, i_y;            /* harmonic-subspace currents [A] (dual three-phase), else NaN */
    double theta_e;             /* electrical angle [rad], [0, 2*pi) */
    double omega_m;             /* mechanical speed [rad/s] */
    double torque;              /* electromagnetic torque [N*m] */
} mk_sample_t;

/* Advance one control period of n sub-intervals (gate codes, durations [ns]) under the load torque `load` (which
 * only the kernel's mechanics reads, mechanics.h); see plant.h pl_advance for the trace arguments. Returns 0, or
 * a negative kernel error code. */
typedef int (*mk_advance_fn)(const void *params, void *state, const int32_t *states, const int64_t *durations_ns,
                             int32_t n, const mech_load_t *load, double trace_dt, double *trace, int32_t trace_cap,
                             ge_period_stats_t *stats);

typedef struct mk_kernel {
    int32_t abi;                /* MK_ABI_VERSION */
    const char *name;           /* the machine kind, for errors */
    int32_t legs;               /* inverter legs = measured phase currents (<= MK_MAX_LEGS) */
    int32_t max_state;          /* largest gate code */
    int32_t trace_columns;      /* doubles per trace row */
    uint64_t params_size;       /* bytes of the kernel's params struct */
    uint64_t state_size;        /* bytes of the kernel's state struct */
    mk_advance_fn advance;
    /* the exact sample at the current plant time (the period start) */
    void (*sample)(const void *params, const void *state, mk_sample_t *out);
    /* dyno: hold the speed at omega_m [rad/s] from now on (mech_hold on the kernel's mechanics) */
    void (*hold_speed)(void *params, void *state, double omega_m);
    /* plant time [ns] */
    uint64_t (*time_ns)(const void *state);
} mk_kernel_t;

/* A kernel's table and its function `const mk_kernel_t *KIND_kernel(void)`, from its typed functions
 *   int advance_fn(const params_t *, state_t *, <the rest as mk_advance_fn>)
 *   void sample_fn(const params_t *, const state_t *, mk_sample_t *)
 * for params and state structs that hold the drive's mechanics as `mech` and the plant time [ns] as `t_ns`
 * (hold_speed is mech_hold on them). At file scope, with no semicolon after it. */
#define MK_KERNEL_TABLE(kind, params_t, state_t, advance_fn, sample_fn, kind_name, legs, max_state, trace_columns) \
    static int kind##_k_advance(const void *p, void *s, const int32_t *states, const int64_t *durations_ns,       \
                                int32_t n, const mech_load_t *load, double trace_dt, double *trace,               \
                                int32_t trace_cap, ge_period_stats_t *stats)                                       \
    {                                                                                                              \
        return advance_fn((const params_t *)p, (state_t *)s, states, durations_ns, n, load, trace_dt, trace,      \
                          trace_cap, stats);                                                                       \
    }                                                                                                              \
    static void kind##_k_sample(const void *p, const void *s, mk_sample_t *out)                                   \
    {                                                                                                              \
        sample_fn((const params_t *)p, (const state_t *)s, out);                                                   \
    }                                                                                                              \
    static void kind##_k_hold_speed(void *p, void *s, double omega_m)                                              \
    {                                                                                                              \
        mech_hold(&((params_t *)p)->mech, &((state_t *)s)->mech, omega_m);                                         \
    }                                                                                                              \
    static uint64_t kind##_k_time_ns(const void *s)                                                                \
    {                                                                                                              \
        return ((const state_t *)s)->t_ns;                                                                         \
    }                                                                                                              \
    static const mk_kernel_t kind##_kernel_table = {                                                               \
        MK_ABI_VERSION, kind_name, legs, max_state, trace_columns, sizeof(params_t), sizeof(state_t),              \
        kind##_k_advance, kind##_k_sample, kind##_k_hold_speed, kind##_k_time_ns,                                  \
    };                                                                                                             \
    const mk_kernel_t *kind##_kernel(void)                                                                         \
    {                                                                                                              \
        return &kind##_kernel_table;                                                                               \
    }

#endif
