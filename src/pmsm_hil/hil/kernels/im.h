/*
 * Exact squirrel-cage induction machine + two-level inverter plant kernel (host side, double precision).
 *
 * Model: the inverse-Gamma equivalent circuit (as motulator), in stator coordinates (alpha-beta, amplitude
 * invariant), with the stator flux psi_s and the rotor flux psi_R as the state:
 *     d psi_s / dt = u_s - Rs i_s
 *     d psi_R / dt = RR i_s - (RR / LM - j omega_e) psi_R,      i_s = (psi_s - psi_R) / Lsigma
 *     T = 1.5 n_p Im{i_s conj(psi_s)},                          omega_e = n_p omega_m
 * Within each sub-interval the inverter voltage is constant in the stator frame; with the speed constant
 * over it (dyno mode: exactly) the system x' = A x + b, x = (psi_s, psi_R) complex, is linear time-invariant
 * and is solved in closed form: x(t) = x_p + exp(A t) (x0 - x_p), x_p = -A^-1 b, and the complex 2x2
 * exponential exp(A t) = exp(m t) (cosh(r t) I + sinh(r t) / r (A - m I)), m = tr(A) / 2, r^2 = m^2 - det(A).
 * Mechanics (mechanics.h), minimum pulse and dead time as the three-phase PMSM kernel (gate_edges.c): in dead time the diode
 * picked by the phase current's sign at the gate edge conducts until that current reaches zero (found on the
 * closed form), then the phase is open and the other two carry one loop current, integrated by RK4 in <= 25 ns
 * steps; two phases open: no current, psi_R decays freely (closed form). Units: SI, plant time in ns.
 */
#ifndef HIL_IM_H
#define HIL_IM_H

#include <stdint.h>

#include "gate_edges.h"
#include "machine_kernel.h"
#include "mechanics.h"

#define IM_MAX_SUBINTERVALS 8
#define IM_TRACE_COLUMNS 6 /* t [s], i_a, i_b, i_c [A], torque [N*m], omega_m [rad/s] */

typedef struct {
    double rs;        /* stator resistance [Ohm], > 0 */
    double rr;        /* rotor resistance of the inverse-Gamma model [Ohm], > 0 */
    double lsigma;    /* leakage inductance [H], > 0 */
    double lm;        /* magnetizing inductance [H], > 0 */
    double vdc;       /* DC-link voltage [V] */
    double t_dead;    /* dead time per leg [s] */
    double t_mpw;     /* minimum pulse width [s] */
    mech_params_t mech; /* the drive's mechanics (mechanics.h) */
    int32_t pole_pairs;
} im_params_t;

typedef struct {
    uint64_t t_ns;        /* plant time [ns] */
    uint64_t trace_k;     /* index of the next trace sample (t = trace_k * trace_dt) */
    double psi_s[2];      /* stator flux, stator frame (alpha, beta) [Wb] */
    double psi_r[2];      /* rotor flux of the inverse-Gamma model, stator frame [Wb] */
    double theta_e;       /* rotor electrical angle n_p * theta_m [rad], wrapped to [0, 2*pi) */
    mech_state_t mech;    /* the shaft's speed (mechanics.h) */
    ge_legs_t legs;       /* the legs' gate edges and dead time (gate_edges.h) */
    int32_t gate;         /* commanded gate code currently applied, 4*Sa + 2*Sb + Sc */
} im_state_t;

typedef ge_period_stats_t im_period_stats_t; /* see gate_edges.h */

/* Advance one control period of n sub-intervals (state codes, durations [ns]); load torque and trace
 * arguments as pl_advance (plant.h). Returns 0 or MK_E_ARGS / MK_E_TRACE_FULL. */
int im_advance(const im_params_t *p, im_state_t *s, const int32_t *states, const int64_t *durations_ns, int32_t n,
               const mech_load_t *load, double trace_dt, double *trace, int32_t trace_cap, im_period_stats_t *stats);

/* The exact sample at the plant time: phase currents, the currents in the rotor-flux frame (i_d along psi_R,
 * i_q ahead of it; the rotor frame theta_e while |psi_R| < 1e-9 Wb), rotor angle, speed, torque. */
void im_sample(const im_params_t *p, const im_state_t *s, mk_sample_t *out);

/* The machine-kernel table of this plant (machine_kernel.h), for the native period loop. */
const mk_kernel_t *im_kernel(void);

#endif
