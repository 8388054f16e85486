/*
 * Exact three-phase PMSM + two-level inverter plant kernel (host side, double precision).
 *
 * Within each sub-interval the inverter applies a voltage that is constant in the STATOR frame;
 * with the rotor speed constant over the sub-interval (dyno mode: exactly) the rotor-frame
 * current equations are linear time-invariant with a sinusoidal input, solved in closed form:
 * matrix exponential of the 2x2 system matrix plus a constant and a rotating particular solution.
 */
#ifndef HIL_PLANT_H
#define HIL_PLANT_H

#include <stdint.h>

#include "gate_edges.h"
#include "machine_kernel.h"
#include "mechanics.h"

#define PL_MAX_SUBINTERVALS 16 /* the 13 segments of six duty cycles (pwm_duty.h) fit */
#define PL_TRACE_COLUMNS 6 /* t [s], i_a, i_b, i_c [A], torque [N*m], omega_m [rad/s] */

typedef struct {
    double rs;        /* stator resistance [Ohm], > 0 */
    double ld;        /* d-axis inductance [H] */
    double lq;        /* q-axis inductance [H] */
    double psi_f;     /* permanent-magnet flux linkage [Wb] */
    double vdc;       /* DC-link voltage [V] */
    double t_dead;    /* dead time per leg [s] */
    double t_mpw;     /* minimum pulse width [s]; shorter pulses never reach the gate */
    mech_params_t mech; /* the drive's mechanics (mechanics.h) */
    int32_t pole_pairs;
} pl_params_t;

typedef struct {
    uint64_t t_ns;        /* plant time [ns] */
    uint64_t trace_k;     /* index of the next trace sample (t = trace_k * trace_dt) */
    double i_d, i_q;      /* rotor-frame currents [A] */
    double theta_e;       /* electrical angle [rad], wrapped to [0, 2*pi) */
    mech_state_t mech;    /* the shaft's speed (mechanics.h) */
    ge_legs_t legs;       /* the legs' gate edges and dead time (gate_edges.h) */
    int32_t gate;         /* commanded gate code currently applied, 4*Sa + 2*Sb + Sc */
} pl_state_t;

typedef ge_period_stats_t pl_period_stats_t; /* see gate_edges.h */

#define PL_OK 0
#define PL_E_ARGS MK_E_ARGS
#define PL_E_TRACE_FULL MK_E_TRACE_FULL

/* Advance the plant over one control period made of n sub-intervals (state codes, durations [ns]) under the load
 * torque `load` (mechanics.h; the mechanics reads it, under a dyno it has no effect).
 * Trace rows (PL_TRACE_COLUMNS doubles each) are written at t = k * trace_dt (trace_dt <= 0: none). */
int pl_advance(const pl_params_t *p, pl_state_t *s, const int32_t *states, const int64_t *durations_ns,
               int32_t n, const mech_load_t *load, double trace_dt, double *trace, int32_t trace_cap,
               pl_period_stats_t *stats);

/* Electromagnetic torque [N*m] for rotor-frame currents [A]. */
double pl_torque(const pl_params_t *p, double i_d, double i_q);

/* Phase currents [A] (amplitude-invariant inverse Park + Clarke). */
void pl_phase_currents(double i_d, double i_q, double theta_e, double *i_a, double *i_b, double *i_c);

/* The machine-kernel table of this plant (machine_kernel.h), for the native period loop. */
const mk_kernel_t *pl_kernel(void);

#endif
