/*
 * Shared core of the plant kernels (plant.c three-phase, plant6.c dual three-phase):
 * the closed-form rotor-frame solution of one sub-interval with a stator-frame voltage that is
 * constant over it, and the time-ordered list of gate events of a control period.
 */
#ifndef HIL_DQ_SEGMENT_H
#define HIL_DQ_SEGMENT_H

#include <complex.h>
#include <stdint.h>

#define DQ_TWO_PI 6.283185307179586476925286766559

/* Solution of di/dt = A i + u(t) for the dq currents over one sub-interval. */
typedef struct {
    double m, delta;          /* A = m I + M, M*M = delta I */
    double M00, M01, M10, M11;
    double x0_const[2];       /* constant particular solution [A] */
    double complex z[2];      /* rotating particular solution amplitude [A] */
    double ea_re, ea_im;      /* exp(j a0), a0: angle of d relative to the stator voltage at tau = 0 */
    double cos_th0, sin_th0;  /* cos, sin of the rotor angle at tau = 0 */
    double omega_e;           /* electrical speed [rad/s] */
    double h0[2];             /* initial homogeneous part x0 - x_p(0) [A] */
} dq_segment_t;

/* Machine constants of the closed form (divisions done once, not per sub-interval). */
typedef struct {
    double rs_ld, rs_lq;     /* rs / ld, rs / lq [1/s] */
    double lq_ld, ld_lq;     /* inductance ratios */
    double psi_lq;           /* psi_f / lq [A] */
    double inv_ld, inv_lq;   /* [1/H] */
    double m;                /* (a00 + a11) / 2 [1/s] */
} dq_machine_t;

/* Constants for stator resistance rs [Ohm], inductances ld, lq [H], magnet flux psi_f [Wb]. */
void dq_machine_init(double rs, double ld, double lq, double psi_f, dq_machine_t *mc);

/* Set up the closed form for electrical speed omega_e [rad/s], rotor angle theta0 [rad], stator-frame
 * voltage (v_alpha, v_beta) [V] and initial currents (i_d0, i_q0) [A]. */
void dq_segment_setup(const dq_machine_t *mc, double omega_e, double theta0, double v_alpha, double v_beta,
                      double i_d0, double i_q0, dq_segment_t *g);

/* dq currents [A] tau seconds into the sub-interval. */
void dq_segment_eval(const dq_segment_t *g, double tau, double *i_d, double *i_q);

/* Rows on an equally spaced grid tau0, tau0 + dt, ... inside one sub-interval, by the addition theorems of
 * exp, C/S and the rotations instead of libm calls per row; restarted from the closed form every
 * DQ_WALK_REANCHOR rows so that rounding cannot accumulate (relative error ~1e-15 against dq_segment_eval). */
#define DQ_WALK_REANCHOR 32
typedef struct {
    double em, em_step;          /* exp(m tau), exp(m dt) */
    double c, s, c_step, s_step; /* C(tau), S(tau) and at dt (exp(M tau) = C I + S M) */
    double e_re, e_im;           /* exp(j (a0 + omega_e tau)): the rotating input's phasor */
    double cos_th, sin_th;       /* cos, sin of the rotor angle theta0 + omega_e tau */
    double rot_re, rot_im;       /* exp(j omega_e dt) */
    int32_t left;                /* rows before the next restart */
} dq_walk_t;

/* Start at tau0 [s] with step dt [s]; em_step = exp(m dt) (the same for every segment of a machine). */
void dq_walk_start(const dq_segment_t *g, double tau0, double dt, double em_step, dq_walk_t *w);
/* dq currents [A] at the walker's tau. */
void dq_walk_eval(const dq_segment_t *g, const dq_walk_t *w, double *i_d, double *i_q);
/* Step by dt: 1, or 0 when the walker must be started afresh (dq_walk_start) at the next row. */
int dq_walk_next(const dq_segment_t *g, dq_walk_t *w);

/* sin and cos of x [rad] (one libm call where the C library has sincos). */
void dq_sincos(double x, double *s, double *c);

/* Angle wrapped to [0, 2*pi). */
double dq_wrap_angle(double theta);

typedef struct {
    double t;     /* absolute time [s] */
    int32_t leg;
    int32_t kind; /* 0: gate edge to level `level`, 1: end of dead time, 2: load breakpoint (leg = index) */
    int32_t level;
} dq_event_t;

/* Insert an event in time order (edges before dead-time ends at equal times); returns the new count,
 * unchanged when the list (capacity cap) is full. */
int dq_add_event(dq_event_t *ev, int n, int cap, double t, int leg, int kind, int level);

#endif
