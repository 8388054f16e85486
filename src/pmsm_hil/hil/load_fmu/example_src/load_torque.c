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
 * binaries/linux64/load_torque.so (FMI 3.0: binaries/x86_64-linux/load_torque.so). fmi_unused.c beside this file
 * holds the rest of the FMI API (stubs) so that tools loading every function, e.g. fmpy's simulate_fmu, load it.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifndef LOAD_FMI
#define LOAD_FMI 2
#endif

#if LOAD_FMI == 3
#include "fmi3Functions.h"
#else
#include "fmi2Functions.h"
#endif

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

/* One communication step of h [s] with the speed held: the lag's exact solution. */
static void load_step(load_t *m, double h)
{
    const double t_ss = load_steady(m, m->v[VR_SPEED]);
    const double tau = m->v[VR_TAU_LAG];
    m->v[VR_TORQUE] = tau > 0.0 ? t_ss + (m->v[VR_TORQUE] - t_ss) * exp(-h / tau) : t_ss;
}

/* ===== FMI glue: variables by value reference, the calls the runner makes ================================ */

typedef struct {
    load_t model;
#if LOAD_FMI == 3
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
#else
    fmi2CallbackFunctions cb;
    char name[64];
#endif
} instance_t;

static void say_error(instance_t *c, const char *text)
{
#if LOAD_FMI == 3
    if (c->log != NULL) {
        c->log(c->env, fmi3Error, "logStatusError", text);
    }
#else
    if (c->cb.logger != NULL) {
        c->cb.logger(c->cb.componentEnvironment, c->name, fmi2Error, "logStatusError", "%s", text);
    }
#endif
}

static instance_t *instance_new(void)
{
    instance_t *c = (instance_t *)calloc(1, sizeof *c);
    if (c != NULL) {
        load_defaults(&c->model);
    }
    return c;
}

/* 0: done; -1: refused (said why). The speed is an input (settable always), parameters before initialisation. */
static int set_values(instance_t *c, const unsigned int *vr, size_t n, const double *value)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        if (vr[i] == 0 || vr[i] >= VR_COUNT || vr[i] == VR_TORQUE) {
            say_error(c, "this variable cannot be set");
            return -1;
        }
        if (c->model.initialised && vr[i] != VR_SPEED) {
            say_error(c, "parameters are fixed after initialisation");
            return -1;
        }
        c->model.v[vr[i]] = value[i];
    }
    return 0;
}

static int get_values(instance_t *c, const unsigned int *vr, size_t n, double *value)
{
    size_t i;
    for (i = 0; i < n; ++i) {
        if (vr[i] == 0 || vr[i] >= VR_COUNT) {
            say_error(c, "unknown value reference");
            return -1;
        }
        value[i] = c->model.v[vr[i]];
    }
    return 0;
}

static int exit_initialisation(instance_t *c)
{
    const char *problem = load_check(&c->model);
    if (problem != NULL) {
        say_error(c, problem);
        return -1;
    }
    load_start(&c->model);
    c->model.initialised = 1;
    return 0;
}

#if LOAD_FMI == 3
fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment, fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate)
{
    instance_t *c;
    (void)instanceName; (void)resourcePath; (void)visible; (void)loggingOn; (void)eventModeUsed;
    (void)earlyReturnAllowed; (void)requiredIntermediateVariables; (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;
    if (instantiationToken == NULL || strcmp(instantiationToken, LOAD_TOKEN) != 0) {
        return NULL; /* another build's model description */
    }
    c = instance_new();
    if (c != NULL) {
        c->env = instanceEnvironment;
        c->log = logMessage;
    }
    return c;
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
    return exit_initialisation((instance_t *)instance) == 0 ? fmi3OK : fmi3Error;
}

fmi3Status fmi3Terminate(fmi3Instance instance) { (void)instance; return fmi3OK; }

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 v[],
                          size_t nv)
{
    (void)nv;
    return set_values((instance_t *)instance, vr, nvr, v) == 0 ? fmi3OK : fmi3Error;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 v[],
                          size_t nv)
{
    (void)nv;
    return get_values((instance_t *)instance, vr, nvr, v) == 0 ? fmi3OK : fmi3Error;
}

/* The runner also looks these up (for Int32 / Boolean parameters); this model has none. */
fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 v[],
                        size_t nv)
{
    (void)vr; (void)nvr; (void)v; (void)nv;
    say_error((instance_t *)instance, "no Int32 variables");
    return fmi3Error;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Boolean v[],
                          size_t nv)
{
    (void)vr; (void)nvr; (void)v; (void)nv;
    say_error((instance_t *)instance, "no Boolean variables");
    return fmi3Error;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime)
{
    (void)noSetFMUStatePriorToCurrentPoint;
    load_step(&((instance_t *)instance)->model, communicationStepSize);
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    *lastSuccessfulTime = currentCommunicationPoint + communicationStepSize;
    return fmi3OK;
}
#else
fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn)
{
    instance_t *c;
    (void)fmuResourceLocation; (void)visible; (void)loggingOn;
    if (fmuType != fmi2CoSimulation || fmuGUID == NULL || strcmp(fmuGUID, LOAD_TOKEN) != 0 || functions == NULL) {
        return NULL; /* not Co-Simulation, or another build's model description */
    }
    c = instance_new();
    if (c != NULL) {
        c->cb = *functions;
        strncpy(c->name, instanceName != NULL ? instanceName : "", sizeof c->name - 1);
    }
    return c;
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
    return exit_initialisation((instance_t *)c) == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[])
{
    return set_values((instance_t *)c, vr, nvr, value) == 0 ? fmi2OK : fmi2Error;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[])
{
    return get_values((instance_t *)c, vr, nvr, value) == 0 ? fmi2OK : fmi2Error;
}

/* The runner also looks these up (for Integer / Boolean parameters); this model has none. */
fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[])
{
    (void)vr; (void)nvr; (void)value;
    say_error((instance_t *)c, "no Integer variables");
    return fmi2Error;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[])
{
    (void)vr; (void)nvr; (void)value;
    say_error((instance_t *)c, "no Boolean variables");
    return fmi2Error;
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint)
{
    (void)currentCommunicationPoint; (void)noSetFMUStatePriorToCurrentPoint;
    load_step(&((instance_t *)c)->model, communicationStepSize);
    return fmi2OK;
}
#endif
