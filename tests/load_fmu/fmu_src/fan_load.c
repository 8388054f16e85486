/*
 * A fan / pump load with a first-order lag, as a Co-Simulation FMU (FMI 2.0 when built with -DLOAD_FMI=2,
 * FMI 3.0 with -DLOAD_FMI=3): input `speed` w [rad/s], output `torque` T [N*m],
 *     tau * dT/dt = k * w * |w| - T,   T(0) = T0,
 * each doStep integrated exactly with w held (T -> T_ss + (T - T_ss) * exp(-h / tau)). Parameters k
 * [N*m*s^2/rad^2], tau [s], T0 [N*m], fail_at [s] (a doStep at t >= fail_at fails: the test of a failing FMU;
 * < 0 never). Built with -DFAN_BAD=N it misbehaves instead at t >= fail_at (in doStep; in
 * ExitInitializationMode with -DFAN_BAD_IN_INIT=1): 1 SIGSEGV, 2 abort(), 3 stack overflow, 4 _exit(0),
 * 5 an endless loop, 6 blocks for good, 7 a torque of 1e30 -- the containment tests' FMUs; with FAN_MARKER set
 * in the environment it first creates that file (the test then knows the FMU is misbehaving). Written for the
 * test suite of this project: the model only, on the example load FMU's FMI glue (fmi_glue.h, fmi_unused.c of
 * src/pmsm_hil/hil/load_fmu/example_src), against the FMI headers fmpy ships.
 */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

#ifndef LOAD_TOKEN
#define LOAD_TOKEN "{7d3c51f0-2a9e-4c55-9e0a-fan-load-test}"
#endif

enum { VR_SPEED = 1, VR_TORQUE = 2, VR_K = 3, VR_TAU = 4, VR_T0 = 5, VR_FAIL_AT = 6, VR_COUNT = 7 };

typedef struct {
    double v[VR_COUNT]; /* by value reference */
    int initialised;
} load_t;

#ifndef FAN_BAD
#define FAN_BAD 0
#endif
#ifndef FAN_BAD_IN_INIT
#define FAN_BAD_IN_INIT 0
#endif

/* Deep enough to overflow any stack (bounded, so the compiler sees an ending). */
static int deep(volatile char *up, long n)
{
    volatile char frame[4096];
    frame[0] = (char)n;
    frame[4095] = up != NULL ? up[0] : 0;
    if (n > 100000000L) {
        return frame[0];
    }
    return deep(frame, n + 1) + frame[4095];
}

/* The FAN_BAD misbehaviour (7, the absurd torque, is the step's own). */
static void misbehave(load_t *f)
{
    const char *marker = getenv("FAN_MARKER");
    volatile int spin = 0;
    if (marker != NULL) {
        FILE *m = fopen(marker, "w");
        if (m != NULL) {
            fclose(m);
        }
    }
    switch (FAN_BAD) {
    case 1:
        *(volatile int *)(void *)(size_t)f->v[0] = 1; /* v[0] is 0.0: a write to address 0 */
        break;
    case 2:
        abort();
    case 3:
        (void)deep(NULL, 0);
        break;
    case 4:
        _exit(0);
    case 5:
        for (;;) {
            spin++;
        }
    case 6:
        for (;;) {
            pause();
        }
    default:
        break;
    }
}

static void load_defaults(load_t *f)
{
    f->v[VR_K] = 2.0e-4;
    f->v[VR_TAU] = 0.02;
    f->v[VR_T0] = 0.0;
    f->v[VR_FAIL_AT] = -1.0;
}

static const char *load_check(load_t *f)
{
    if (FAN_BAD_IN_INIT) {
        misbehave(f);
    }
    return NULL;
}

static void load_start(load_t *f) { f->v[VR_TORQUE] = f->v[VR_T0]; }

static const char *load_step(load_t *f, double t, double h)
{
    const double w = f->v[VR_SPEED];
    const double t_ss = f->v[VR_K] * w * fabs(w);
    if (f->v[VR_FAIL_AT] >= 0.0 && t >= f->v[VR_FAIL_AT]) {
        if (FAN_BAD == 7) {
            f->v[VR_TORQUE] = 1e30;
            return NULL;
        }
        if (FAN_BAD != 0 && !FAN_BAD_IN_INIT) {
            misbehave(f);
        }
        return "fan blade jammed (fail_at reached)";
    }
    f->v[VR_TORQUE] = f->v[VR_TAU] > 0.0 ? t_ss + (f->v[VR_TORQUE] - t_ss) * exp(-h / f->v[VR_TAU]) : t_ss;
    return NULL;
}

#include "fmi_glue.h"
