/*
 * The drive's mechanics, shared by every machine kernel: the shaft speed the electrical model turns at, the load
 * torque acting on it, and how the two move the speed.
 *
 * A kernel's electrical model is exact at constant speed; mech_integrate cuts an interval of constant gate levels
 * into constant-speed pieces (at most max_piece long while the speed moves), lets the kernel advance its
 * electrical state over each piece at the speed the mechanics holds, and then advances the speed from the
 * kernel's air-gap torque at the piece's two ends and the load torque at its middle. Modes:
 *   MECH_DYNO      the speed is held (a dyno): no piece limit, no speed update;
 *   MECH_INERTIA   one mass: J dw/dt = Te - T_load - B w, trapezoidal torque, implicit friction;
 *   MECH_TWO_MASS  motor mass J and load mass j_load on a shaft of stiffness k_shaft and damping c_shaft:
 *                      J dw/dt      = Te - B w - k tw - c (w - w_l)
 *                      j_load dw_l/dt = k tw + c (w - w_l) - T_load,     d tw/dt = w - w_l
 *                  (the load torque acts on the load mass; trapezoidal rule per piece).
 * Units: SI (rad/s mechanical, N*m, kg*m^2, s).
 */
#ifndef HIL_MECHANICS_H
#define HIL_MECHANICS_H

#include <stdint.h>

#define MECH_DYNO 0     /* the speed is held */
#define MECH_INERTIA 1  /* one mass with viscous friction */
#define MECH_TWO_MASS 2 /* motor and load masses on an elastic shaft */

typedef struct {
    double j;         /* motor-side inertia [kg*m^2] (one mass: the whole drive's) */
    double b;         /* viscous friction on the motor side [N*m*s/rad] */
    double max_piece; /* longest constant-speed piece while the speed moves [s] (<= 0: no limit) */
    double j_load;    /* two-mass: load-side inertia [kg*m^2] */
    double k_shaft;   /* two-mass: shaft stiffness [N*m/rad] */
    double c_shaft;   /* two-mass: shaft damping [N*m*s/rad] */
    int32_t mode;     /* MECH_DYNO, MECH_INERTIA or MECH_TWO_MASS */
} mech_params_t;

typedef struct {
    double omega_m; /* motor-side (rotor) speed [rad/s]: the speed the electrical model turns at */
    double omega_l; /* two-mass: load-side speed [rad/s] */
    double twist;   /* two-mass: shaft twist, rotor angle minus load angle [rad] */
} mech_state_t;

/* The load torque over one control period: value at the period start [N*m] plus slope [N*m/s] times the time
 * since, then from each breakpoint inside the period (bp: n_bp triplets of absolute time [s], value [N*m],
 * slope [N*m/s]) the segment it starts. */
typedef struct {
    double value;
    double slope;
    const double *bp;
    int32_t n_bp;
} mech_load_t;

/* The load segment in force: value + slope * (t - t_ref) [N*m], t absolute [s]. */
typedef struct {
    double t_ref;
    double value;
    double slope;
} mech_segment_t;

/* The kernel's electrical model over one piece from absolute time t0 [s] at the constant mechanical speed
 * omega_m [rad/s]; it may shorten *piece (an event inside it, e.g. a diode blocking). Returns 0 or an error. */
typedef int (*mech_piece_fn)(void *ctx, double t0, double *piece, double omega_m);
/* The air-gap torque of the kernel's present electrical state [N*m]. */
typedef double (*mech_torque_fn)(const void *ctx);

/* Advance h seconds from absolute time t_abs [s] under the load segment `load`: constant-speed pieces of the
 * kernel's electrical model, the speed moved between them. Returns 0 or the piece function's error. */
int mech_integrate(const mech_params_t *p, mech_state_t *s, const mech_segment_t *load, double t_abs, double h,
                   mech_piece_fn piece_fn, mech_torque_fn torque_fn, void *ctx);

/* Move the speed over one piece [s] from the air-gap torque at its start and end [N*m] and the load torque at
 * its middle [N*m] (no effect under a dyno). */
void mech_step(const mech_params_t *p, mech_state_t *s, double piece, double te0, double te1, double t_load);

/* Dyno from now on: hold the speed at omega_m [rad/s] (both masses, shaft untwisted). */
void mech_hold(mech_params_t *p, mech_state_t *s, double omega_m);

#endif
