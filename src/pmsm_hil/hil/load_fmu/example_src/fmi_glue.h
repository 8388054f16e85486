/*
 * fmi_glue.h -- the FMI 2.0 / 3.0 Co-Simulation functions the runner calls (`hil run --load-fmu`), in terms of a load
 * model. Included at the end of a model's C file (load_torque.c), which defines before it
 *     LOAD_TOKEN                        the instantiation token (FMI 3) / guid (FMI 2) of modelDescription.xml
 *     VR_SPEED, VR_TORQUE, VR_COUNT     value references: input speed [rad/s], output torque [N*m], one past the last
 *     load_t                            { double v[VR_COUNT]; int initialised; } at least: variables by reference
 *     load_defaults(m)                  the start values
 *     load_check(m) -> text or NULL     parameters checked at initialisation
 *     load_start(m)                     the state at the start
 *     load_step(m, t, h) -> text or NULL  one communication step from t over h [s]; a text fails the step
 * -DLOAD_FMI=2 (default) or 3 picks the API. Written by `hil fmu example` with load_torque.c; nothing here to edit.
 */
#ifndef FMI_GLUE_H
#define FMI_GLUE_H

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

static int do_step(instance_t *c, double t, double h)
{
    const char *problem = load_step(&c->model, t, h);
    if (problem != NULL) {
        say_error(c, problem);
        return -1;
    }
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
    *eventHandlingNeeded = fmi3False;
    *terminateSimulation = fmi3False;
    *earlyReturn = fmi3False;
    if (do_step((instance_t *)instance, currentCommunicationPoint, communicationStepSize) != 0) {
        *lastSuccessfulTime = currentCommunicationPoint;
        return fmi3Error;
    }
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
    (void)noSetFMUStatePriorToCurrentPoint;
    return do_step((instance_t *)c, currentCommunicationPoint, communicationStepSize) == 0 ? fmi2OK : fmi2Error;
}
#endif

#endif /* FMI_GLUE_H */
