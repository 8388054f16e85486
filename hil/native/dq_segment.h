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
    double a0;                /* angle of the stator voltage relative to d at tau = 0 [rad] */
    double omega_e;           /* electrical speed [rad/s] */
    double h0[2];             /* initial homogeneous part x0 - x_p(0) [A] */
} dq_segment_t;

/* Set up the closed form for stator resistance rs [Ohm], inductances ld, lq [H], magnet flux psi_f [Wb],
 * electrical speed omega_e [rad/s], rotor angle theta0 [rad], stator-frame voltage (v_alpha, v_beta) [V]
 * and initial currents (i_d0, i_q0) [A]. */
void dq_segment_setup(double rs, double ld, double lq, double psi_f, double omega_e, double theta0,
                      double v_alpha, double v_beta, double i_d0, double i_q0, dq_segment_t *g);

/* dq currents [A] tau seconds into the sub-interval. */
void dq_segment_eval(const dq_segment_t *g, double tau, double *i_d, double *i_q);

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
