/*
 * A fan / pump load with a first-order lag, as a Co-Simulation FMU (FMI 2.0 when built with -DFAN_FMI=2,
 * FMI 3.0 with -DFAN_FMI=3): input `speed` w [rad/s], output `torque` T [N*m],
 *     tau * dT/dt = k * w * |w| - T,   T(0) = T0,
 * each doStep integrated exactly with w held (T -> T_ss + (T - T_ss) * exp(-h / tau)). Parameters k
 * [N*m*s^2/rad^2], tau [s], T0 [N*m], fail_at [s] (a doStep at t >= fail_at fails: the test of a failing FMU;
 * < 0 never). Built with -DFAN_BAD=N it misbehaves instead at t >= fail_at (in doStep; in
 * ExitInitializationMode with -DFAN_BAD_IN_INIT=1): 1 SIGSEGV, 2 abort(), 3 stack overflow, 4 _exit(0),
 * 5 an endless loop, 6 blocks for good, 7 a torque of 1e30 -- the containment tests' FMUs; with FAN_MARKER set
 * in the environment it first creates that file (the test then knows the FMU is misbehaving). Written for the
 * test suite of this project against the FMI headers fmpy ships.
 */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#if FAN_FMI == 3
#include "fmi3Functions.h"
#define STATUS fmi3Status
#define OK fmi3OK
#define ERROR fmi3Error
#else
#include "fmi2Functions.h"
#define STATUS fmi2Status
#define OK fmi2OK
#define ERROR fmi2Error
#endif

#ifndef FAN_TOKEN
#define FAN_TOKEN "{7d3c51f0-2a9e-4c55-9e0a-fan-load-test}"
#endif

enum { VR_SPEED = 1, VR_TORQUE = 2, VR_K = 3, VR_TAU = 4, VR_T0 = 5, VR_FAIL_AT = 6, VR_N = 7 };

typedef struct {
    double v[VR_N];              /* by value reference */
    int initialised;
#if FAN_FMI == 3
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
#else
    fmi2CallbackFunctions cb;
    char name[64];
#endif
} fan_t;

static void say_error(fan_t *f, const char *text)
{
#if FAN_FMI == 3
    if (f->log != NULL) {
        f->log(f->env, fmi3Error, "logStatusError", text);
    }
#else
    if (f->cb.logger != NULL) {
        f->cb.logger(f->cb.componentEnvironment, f->name, fmi2Error, "logStatusError", "%s", text);
    }
#endif
}

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
static void misbehave(fan_t *f)
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

static fan_t *fan_new(void)
{
    fan_t *f = (fan_t *)calloc(1, sizeof *f);
    if (f != NULL) {
        f->v[VR_K] = 2.0e-4;
        f->v[VR_TAU] = 0.02;
        f->v[VR_T0] = 0.0;
        f->v[VR_FAIL_AT] = -1.0;
    }
    return f;
}

static STATUS fan_set(fan_t *f, const unsigned int *vr, size_t n, const double *value)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        if (vr[i] == VR_TORQUE || vr[i] == 0 || vr[i] >= VR_N || (f->initialised && vr[i] != VR_SPEED)) {
            say_error(f, "variable cannot be set");
            return ERROR;
        }
        f->v[vr[i]] = value[i];
    }
    return OK;
}

static STATUS fan_get(fan_t *f, const unsigned int *vr, size_t n, double *value)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        if (vr[i] == 0 || vr[i] >= VR_N) {
            say_error(f, "unknown value reference");
            return ERROR;
        }
        value[i] = f->v[vr[i]];
    }
    return OK;
}

static STATUS fan_step(fan_t *f, double t, double h)
{
    const double w = f->v[VR_SPEED];
    const double t_ss = f->v[VR_K] * w * fabs(w);
    if (f->v[VR_FAIL_AT] >= 0.0 && t >= f->v[VR_FAIL_AT]) {
        if (FAN_BAD == 7) {
            f->v[VR_TORQUE] = 1e30;
            return OK;
        }
        if (FAN_BAD != 0 && !FAN_BAD_IN_INIT) {
            misbehave(f);
        }
        say_error(f, "fan blade jammed (fail_at reached)");
        return ERROR;
    }
    if (f->v[VR_TAU] > 0.0) {
        f->v[VR_TORQUE] = t_ss + (f->v[VR_TORQUE] - t_ss) * exp(-h / f->v[VR_TAU]);
    } else {
        f->v[VR_TORQUE] = t_ss;
    }
    return OK;
}

#if FAN_FMI == 3
fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    fan_t *f;
    (void)instanceName; (void)resourcePath; (void)visible; (void)loggingOn; (void)eventModeUsed;
    (void)earlyReturnAllowed; (void)requiredIntermediateVariables; (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    if (instantiationToken == NULL || strcmp(instantiationToken, FAN_TOKEN) != 0) {
        return NULL;
    }
    f = fan_new();
    if (f != NULL) {
        f->env = instanceEnvironment;
        f->log = logMessage;
    }
    return f;
}

void fmi3FreeInstance(fmi3Instance instance) { free(instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime)
{
    (void)instance; (void)toleranceDefined; (void)tolerance; (void)startTime; (void)stopTimeDefined; (void)stopTime;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance)
{
    fan_t *f = (fan_t *)instance;
    if (FAN_BAD_IN_INIT) {
        misbehave(f);
    }
    f->v[VR_TORQUE] = f->v[VR_T0];
    f->initialised = 1;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) { (void)instance; return fmi3OK; }

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 v[],
                          size_t nv)
{
    (void)nv;
    return fan_set((fan_t *)instance, vr, nvr, v);
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 v[],
                          size_t nv)
{
    (void)nv;
    return fan_get((fan_t *)instance, vr, nvr, v);
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 v[],
                        size_t nv)
{
    (void)vr; (void)nvr; (void)v; (void)nv;
    say_error((fan_t *)instance, "no Int32 variables");
    return fmi3Error;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Boolean v[],
                          size_t nv)
{
    (void)vr; (void)nvr; (void)v; (void)nv;
    say_error((fan_t *)instance, "no Boolean variables");
    return fmi3Error;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime)
{
    fmi3Status s;
    (void)noSetFMUStatePriorToCurrentPoint;
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    s = fan_step((fan_t *)instance, currentCommunicationPoint, communicationStepSize);
    *lastSuccessfulTime = currentCommunicationPoint + (s == fmi3OK ? communicationStepSize : 0.0);
    return s;
}
#else
fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    fan_t *f;
    (void)fmuResourceLocation; (void)visible; (void)loggingOn;
    if (fmuType != fmi2CoSimulation || fmuGUID == NULL || strcmp(fmuGUID, FAN_TOKEN) != 0 || functions == NULL) {
        return NULL;
    }
    f = fan_new();
    if (f != NULL) {
        f->cb = *functions;
        strncpy(f->name, instanceName != NULL ? instanceName : "", sizeof f->name - 1);
    }
    return f;
}

void fmi2FreeInstance(fmi2Component c) { free(c); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime)
{
    (void)c; (void)toleranceDefined; (void)tolerance; (void)startTime; (void)stopTimeDefined; (void)stopTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }

fmi2Status fmi2ExitInitializationMode(fmi2Component c)
{
    fan_t *f = (fan_t *)c;
    if (FAN_BAD_IN_INIT) {
        misbehave(f);
    }
    f->v[VR_TORQUE] = f->v[VR_T0];
    f->initialised = 1;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    return fan_set((fan_t *)c, vr, nvr, value);
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    return fan_get((fan_t *)c, vr, nvr, value);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    (void)vr; (void)nvr; (void)value;
    say_error((fan_t *)c, "no Integer variables");
    return fmi2Error;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    (void)vr; (void)nvr; (void)value;
    say_error((fan_t *)c, "no Boolean variables");
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    return fan_step((fan_t *)c, currentCommunicationPoint, communicationStepSize);
}
#endif
