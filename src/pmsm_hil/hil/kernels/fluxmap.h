/*
 * Saturated three-phase PMSM from a flux map (kind "pmsm-fluxmap") + two-level inverter, host side, double precision.
 *
 * The state is the rotor-frame flux linkage psi = (psi_d, psi_q); the currents come from the inverted map
 * i = psi^-1(psi). The map psi(i) is a piecewise bicubic Hermite interpolant (C1) of the user's grid whose
 * per-cell coefficients the Python side computes (src/pmsm_hil/hil/fluxmap.py: node slopes by PCHIP along each axis); outside
 * the grid it continues to first order from the nearest grid point. The inverse is Newton's method on that
 * interpolant, warm-started from the last currents. Within a sub-interval the stator-frame voltage is constant and
 *     d psi_d/dt = v_d - Rs i_d + omega_e psi_q,   d psi_q/dt = v_q - Rs i_q - omega_e psi_d
 * with (v_d, v_q) the stator voltage rotated by -theta(t), theta(t) = theta0 + omega_e t; it is integrated by the
 * embedded Dormand-Prince 5(4) pair with error control: each step's error estimate, turned into current by the
 * map's largest inverse incremental inductance, stays below tol_i. Dead time as plant.c: a leg in dead time
 * conducts through the diode its current's sign chose until that current reaches zero (found by bisection to
 * 1e-13 s), then its phase is open: its terminal floats to the potential that keeps its current at zero (solved
 * inside the right-hand side); with two phases open no current flows and the flux rests at the map's psi(0, 0).
 *
 * The map arrays are not copied: the params struct points to arrays the Python plant keeps alive (any grid size).
 * Units: SI (A, V, Wb, Ohm, H, rad, rad/s, s), time in ns.
 */
#ifndef HIL_FLUXMAP_H
#define HIL_FLUXMAP_H

#include <stdint.h>

#include "gate_edges.h"
#include "machine_kernel.h"
#include "mechanics.h"

#define FM_TRACE_COLUMNS 6 /* t [s], i_a, i_b, i_c [A], torque [N*m], omega_m [rad/s] */
#define FM_COEFS 16        /* bicubic coefficients a[4*m + n] of u^m v^n per cell and function */
#define FM_E_NEWTON (-10)  /* no current found for a flux (Newton did not converge, or a singular map) */
#define FM_E_STEP (-11)    /* the step size fell below 1e-15 s (error control could not be met) */

typedef struct {
    double rs;        /* stator resistance [Ohm] */
    double vdc;       /* DC link [V] */
    double t_dead;    /* dead time per leg [s] */
    double t_mpw;     /* minimum pulse width [s] */
    mech_params_t mech; /* the drive's mechanics (mechanics.h) */
    double tol_i;     /* local error tolerance per step, in current [A] */
    double inv_l_max; /* largest inf-norm of the inverse incremental inductance matrix over the grid [1/H] */
    const double *id_axis; /* nx ascending grid currents [A] */
    const double *iq_axis; /* ny ascending grid currents [A] */
    const double *coef_d;  /* (nx-1)*(ny-1) cells (cell index ix*(ny-1)+iy) x FM_COEFS, psi_d [Wb] */
    const double *coef_q;  /* the same for psi_q [Wb] */
    int32_t nx;
    int32_t ny;
    int32_t pole_pairs;
} fm_params_t;

typedef struct {
    uint64_t t_ns;        /* plant time [ns] */
    uint64_t trace_k;     /* index of the next trace sample (t = trace_k * trace_dt) */
    double psi_d, psi_q;  /* rotor-frame flux linkage [Wb]: the state */
    double i_d, i_q;      /* the currents of that flux [A] (inverse map) */
    double theta_e;       /* electrical angle [rad], wrapped to [0, 2*pi) */
    mech_state_t mech;    /* the shaft's speed (mechanics.h) */
    double h_last;        /* last accepted step [s] (the next step's first try) */
    uint64_t steps;       /* accepted integration steps since the start */
    uint64_t rejected;    /* rejected steps since the start */
    ge_legs_t legs;       /* the legs' gate edges and dead time (gate_edges.h) */
    int32_t gate;         /* applied gate code 4*Sa + 2*Sb + Sc */
} fm_state_t;

typedef ge_period_stats_t fm_period_stats_t;

/* The map: flux linkage [Wb] at currents [A], and its Jacobian (incremental inductances [H]: l[0] = dpsi_d/di_d,
 * l[1] = dpsi_d/di_q, l[2] = dpsi_q/di_d, l[3] = dpsi_q/di_q; l may be NULL). */
void fm_flux(const fm_params_t *p, double i_d, double i_q, double *psi_d, double *psi_q, double *l);

/* The inverse map: currents [A] of a flux [Wb], Newton from the guess in *i_d, *i_q; 0 or FM_E_NEWTON. */
int fm_currents(const fm_params_t *p, double psi_d, double psi_q, double *i_d, double *i_q);

/* Advance one control period (see plant.h pl_advance for the load and trace arguments). */
int fm_advance(const fm_params_t *p, fm_state_t *s, const int32_t *states, const int64_t *durations_ns, int32_t n,
               const mech_load_t *load, double trace_dt, double *trace, int32_t trace_cap, fm_period_stats_t *stats);

/* The exact state at the plant time: phase currents, dq currents, angle, speed, torque 1.5 p (psi_d i_q - psi_q i_d). */
void fm_sample(const fm_params_t *p, const fm_state_t *s, mk_sample_t *out);

/* The machine-kernel table of this plant (machine_kernel.h). */
const mk_kernel_t *fm_kernel(void);

#endif
