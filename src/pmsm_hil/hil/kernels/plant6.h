/*
 * Exact dual three-phase PMSM + six-leg two-level inverter plant kernel (host side, double precision).
 *
 * Vector space decomposition (amplitude invariant, factor 1/3): phases A, B, C at 0, 120, 240 deg and
 * U, V, W at 30, 150, 270 deg, two isolated neutrals. The alpha-beta (torque) subspace is solved in the
 * rotor dq frame exactly as the three-phase kernel does (closed form, stator-frame voltage constant
 * per sub-interval); the x-y subspace is a decoupled R - L_ls circuit in the STATIONARY frame, solved
 * as a first-order exponential. The zero-sequence subspaces carry no current (isolated neutrals).
 * State code: 6 bits [S_A S_B S_C S_U S_V S_W], S_A the most significant.
 */
#ifndef HIL_PLANT6_H
#define HIL_PLANT6_H

#include <stdint.h>

#include "gate_edges.h"
#include "machine_kernel.h"
#include "mechanics.h"

#define P6_MAX_SUBINTERVALS 16 /* the 13 segments of six duty cycles (pwm_duty.h) fit */
#define P6_LEGS 6
/* t [s], i_a, i_b, i_c, i_u, i_v, i_w [A], torque [N*m], omega_m [rad/s], i_x, i_y [A] */
#define P6_TRACE_COLUMNS 11

typedef struct {
    double rs;        /* stator resistance [Ohm], > 0 */
    double ld, lq;    /* dq inductances [H], > 0 */
    double lls;       /* leakage inductance of the x-y subspace [H], > 0 */
    double psi_f;     /* permanent-magnet flux linkage [Wb] */
    double vdc;       /* DC-link voltage [V] */
    double t_dead;    /* dead time per leg [s] */
    double t_mpw;     /* minimum pulse width [s]; shorter pulses never reach the gate */
    mech_params_t mech; /* the drive's mechanics (mechanics.h) */
    int32_t pole_pairs;
} p6_params_t;

typedef struct {
    uint64_t t_ns;            /* plant time [ns] */
    uint64_t trace_k;         /* index of the next trace sample */
    double i_d, i_q;          /* rotor-frame currents [A] */
    double i_x, i_y;          /* stationary x-y currents [A] */
    double theta_e;           /* electrical angle [rad], [0, 2*pi) */
    mech_state_t mech;        /* the shaft's speed (mechanics.h) */
    ge_legs_t legs;              /* the legs' gate edges and dead time (gate_edges.h) */
    int32_t gate;                /* applied gate code (6 bits) */
} p6_state_t;

typedef ge_period_stats_t p6_period_stats_t; /* see gate_edges.h */

#define P6_OK 0
#define P6_E_ARGS MK_E_ARGS
#define P6_E_TRACE_FULL MK_E_TRACE_FULL

/* Advance one control period of n sub-intervals (6-bit state codes, durations [ns]); see plant.h. */
int p6_advance(const p6_params_t *p, p6_state_t *s, const int32_t *states, const int64_t *durations_ns,
               int32_t n, const mech_load_t *load, double trace_dt, double *trace, int32_t trace_cap,
               p6_period_stats_t *stats);

/* Electromagnetic torque 3*p*(psi_d*i_q - psi_q*i_d) [N*m]. */
double p6_torque(const p6_params_t *p, double i_d, double i_q);

/* Six phase currents [A] (A, B, C, U, V, W) from dq, theta_e and x-y (inverse VSD). */
void p6_phase_currents(double i_d, double i_q, double theta_e, double i_x, double i_y, double *i_phase);

/* Stator-frame voltages [V] (alpha, beta, x, y) of a 6-bit leg-level code. */
void p6_code_voltage(double vdc, int32_t code, double *v4);

/* The machine-kernel table of this plant (machine_kernel.h), for the native period loop. */
const mk_kernel_t *p6_kernel(void);

#endif
