/*
 * load_torque.c -- a mechanical load for `hil run --load-fmu`, as an FMI 2.0 or FMI 3.0 Co-Simulation FMU.
 * Written by `hil fmu example DIR`: edit THE MODEL below, then rebuild with `hil fmu build DIR`.
 *
 * Interface (the names `hil run --load-fmu` looks for; others with --load-fmu-map speed=...,torque=...):
 *     input  speed   w [rad/s]  mechanical shaft speed, sampled at the start of each control period
 *     output torque  T [N*m]    load torque, held over the period; positive brakes a positive speed
 *
 * The law: a steady torque of three familiar parts, reached through an optional first-order lag,
 *     T_ss(w) = t_coulomb * tanh(w / w_smooth)      constant (Coulomb) friction, smoothed through w = 0
 *             + b_viscous * w                       viscous friction
 *             + k_quadratic * w * |w|               fan / pump / aerodynamic drag
 *     tau_lag * dT/dt = T_ss(w) - T                 (tau_lag = 0: T = T_ss(w) at once)
 * Each doStep(h) integrates the lag exactly with w held over the step: T <- T_ss + (T - T_ss) * exp(-h / tau_lag).
 * The run sets `speed` before initialisation, so the FMU starts at its steady torque T_ss(w0): a bumpless start.
 *
 * Parameters (fixed: set before initialisation, `hil run --load-fmu-set NAME=VALUE`):
 *     t_coulomb    [N*m]             0.5
 *     w_smooth     [rad/s]           1.0     > 0
 *     b_viscous    [N*m*s/rad]       1e-3
 *     k_quadratic  [N*m*s^2/rad^2]   1e-4
 *     tau_lag      [s]               0.0     >= 0
 * A load inertia is not a torque of this FMU: add it to the motor's (`hil run --set j=J_MOTOR+J_LOAD`), where the
 * runner integrates the speed.
 *
 * One file for both FMI versions: -DLOAD_FMI=2 (default) or -DLOAD_FMI=3 picks the API; the model part is the
 * same. `hil fmu build` compiles it with the host's C compiler against the FMI headers fmpy ships,
 *     cc -std=c99 -O2 -fPIC -shared -Wall -Wextra -Werror -DLOAD_FMI=2 -I<fmpy>/c-code load_torque.c \
 *        fmi_unused.c -o load_torque.so -lm
 * and zips it with modelDescription.xml (its value references are the VR_ numbers below) as
 * binaries/linux64/load_torque.so (FMI 3.0: binaries/x86_64-linux/load_torque.so). Beside this file, fmi_glue.h
 * (included at the end) turns the model into the FMI calls the runner makes, and fmi_unused.c holds the rest of the
 * FMI API (stubs) so that tools loading every function, e.g. fmpy's simulate_fmu, load it.
 */
#include <math.h>
#include <stddef.h>

/* The instantiation token (FMI 3) / guid (FMI 2) of modelDescription.xml: change both together. */
#define LOAD_TOKEN "{5f0c7a2e-8d1b-4c3e-9a6f-hil-load-torque-1}"

/* ===== THE MODEL ============================================================================================ */

/* Value references: the modelDescription.xml's valueReference of each variable. */
enum { VR_SPEED = 1, VR_TORQUE, VR_T_COULOMB, VR_W_SMOOTH, VR_B_VISCOUS, VR_K_QUADRATIC, VR_TAU_LAG, VR_COUNT };

typedef struct {
    double v[VR_COUNT]; /* every variable by its value reference (v[0] unused) */
    int initialised;    /* parameters are fixed from then on */
} load_t;

/* Start values: the same as modelDescription.xml's `start`. */
static void load_defaults(load_t *m)
{
    m->v[VR_SPEED] = 0.0;
    m->v[VR_TORQUE] = 0.0;
    m->v[VR_T_COULOMB] = 0.5;
    m->v[VR_W_SMOOTH] = 1.0;
    m->v[VR_B_VISCOUS] = 1.0e-3;
    m->v[VR_K_QUADRATIC] = 1.0e-4;
    m->v[VR_TAU_LAG] = 0.0;
}

/* The steady torque T_ss(w) [N*m] at speed w [rad/s]. */
static double load_steady(const load_t *m, double w)
{
    return m->v[VR_T_COULOMB] * tanh(w / m->v[VR_W_SMOOTH]) + m->v[VR_B_VISCOUS] * w
           + m->v[VR_K_QUADRATIC] * w * fabs(w);
}

/* Parameters checked at initialisation: NULL when usable, else what is wrong. */
static const char *load_check(const load_t *m)
{
    if (!(m->v[VR_W_SMOOTH] > 0.0)) {
        return "w_smooth must be > 0";
    }
    if (!(m->v[VR_TAU_LAG] >= 0.0)) {
        return "tau_lag must be >= 0";
    }
    return NULL;
}

/* The state at the start: the steady torque at the speed the run set. */
static void load_start(load_t *m)
{
    m->v[VR_TORQUE] = load_steady(m, m->v[VR_SPEED]);
}

/* One communication step from t [s] over h [s] with the speed held: the lag's exact solution. NULL when done,
 * else why the step failed (the run then stops with that reason). */
static const char *load_step(load_t *m, double t, double h)
{
    const double t_ss = load_steady(m, m->v[VR_SPEED]);
    const double tau = m->v[VR_TAU_LAG];
    (void)t;
    m->v[VR_TORQUE] = tau > 0.0 ? t_ss + (m->v[VR_TORQUE] - t_ss) * exp(-h / tau) : t_ss;
    return NULL;
}

/* The FMI functions the runner calls, in terms of the model above (nothing there to edit). */
#include "fmi_glue.h"
