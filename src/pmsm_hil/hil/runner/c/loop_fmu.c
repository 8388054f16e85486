/* The load FMU of the C period loop (loop_fmu.h) in this process: FMI 2.0 / 3.0 Co-Simulation through
 * dlopen/dlsym (nl_fmu_local_*; loop_fmu_box.c calls them here, or in the FMU's own process). The FMI headers
 * are fmpy's (its c-code folder, found at build time by src/pmsm_hil/hil/runner/c/_build_loop.py). */
#define _POSIX_C_SOURCE 200809L

#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <stdint.h>

#include "fmi2FunctionTypes.h"
#include "fmi3FunctionTypes.h"
#include "loop_fmu.h"

/* f->fn[] slots. FMI 2 names the first, FMI 3 the second. */
enum {
    FN_INSTANTIATE,   /* fmi2Instantiate, fmi3InstantiateCoSimulation */
    FN_SETUP,         /* fmi2SetupExperiment, - */
    FN_ENTER_INIT,    /* fmi2EnterInitializationMode, fmi3EnterInitializationMode */
    FN_EXIT_INIT,     /* fmi2ExitInitializationMode, fmi3ExitInitializationMode */
    FN_SET_REAL,      /* fmi2SetReal, fmi3SetFloat64 */
    FN_GET_REAL,      /* fmi2GetReal, fmi3GetFloat64 */
    FN_SET_INTEGER,   /* fmi2SetInteger, fmi3SetInt32 */
    FN_SET_BOOLEAN,   /* fmi2SetBoolean, fmi3SetBoolean */
    FN_DO_STEP,       /* fmi2DoStep, fmi3DoStep */
    FN_TERMINATE,     /* fmi2Terminate, fmi3Terminate */
    FN_FREE,          /* fmi2FreeInstance, fmi3FreeInstance */
    FN_COUNT
};

static const char *const FMI2_NAMES[FN_COUNT] = {
    "fmi2Instantiate", "fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode",
    "fmi2SetReal", "fmi2GetReal", "fmi2SetInteger", "fmi2SetBoolean", "fmi2DoStep", "fmi2Terminate",
    "fmi2FreeInstance"};
static const char *const FMI3_NAMES[FN_COUNT] = {
    "fmi3InstantiateCoSimulation", NULL, "fmi3EnterInitializationMode", "fmi3ExitInitializationMode",
    "fmi3SetFloat64", "fmi3GetFloat64", "fmi3SetInt32", "fmi3SetBoolean", "fmi3DoStep", "fmi3Terminate",
    "fmi3FreeInstance"};

typedef char fn_slots_fit[(sizeof(((nl_fmu_t *)0)->fn) / sizeof(void *) >= FN_COUNT) ? 1 : -1];
typedef char callbacks_fit[(sizeof(((nl_fmu_t *)0)->callbacks) >= sizeof(fmi2CallbackFunctions)) ? 1 : -1];

/* A function pointer from dlsym (POSIX: object and function pointers convert). */
#define FN(f, slot, type) (*(type *)(void *)&(f)->fn[slot])

/* Status values at and above which a call failed: fmi2Discard / fmi3Discard (2) (warnings: 1). */
#define STATUS_WARNING 1
#define STATUS_FAILED 2

/* "[category] text" into f->message (cut to its size). */
static void keep_message(nl_fmu_t *f, const char *category, const char *text)
{
    size_t n = 0;
    size_t len;
    if (category != NULL && category[0] != '\0') {
        const int w = snprintf(f->message, sizeof f->message, "[%.64s] ", category);
        n = w > 0 ? (size_t)w : 0u;
    }
    len = strlen(text);
    if (len > sizeof f->message - 1u - n) {
        len = sizeof f->message - 1u - n;
    }
    memcpy(f->message + n, text, len);
    f->message[n + len] = '\0';
}

/* FMI 2 logger: warnings and errors are kept (the last one), the rest dropped. */
static void fmi2_logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                        fmi2String message, ...)
{
    nl_fmu_t *f = (nl_fmu_t *)env;
    char text[NL_FMU_MESSAGE];
    va_list args;
    (void)instance;
    if (f == NULL || message == NULL || (int)status < STATUS_WARNING) {
        return;
    }
    va_start(args, message);
    (void)vsnprintf(text, sizeof text, message, args);
    va_end(args);
    keep_message(f, category, text);
}

static void fmi3_logger(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message)
{
    nl_fmu_t *f = (nl_fmu_t *)env;
    if (f == NULL || message == NULL || (int)status < STATUS_WARNING) {
        return;
    }
    keep_message(f, category, message);
}

static int32_t fail(nl_fmu_t *f, int32_t call, int32_t status, double t)
{
    if (f->failed_call == NL_FMU_CALL_NONE) {
        f->failed_call = call;
        f->status = status;
        f->t_fail = t;
    }
    return -1;
}

/* The status of an FMI call: 0 ok (a warning counted), -1 failed. */
static int32_t check(nl_fmu_t *f, int status, int32_t call, double t)
{
    if (status >= STATUS_FAILED) {
        return fail(f, call, status, t);
    }
    if (status == STATUS_WARNING) {
        f->warnings++;
    }
    return 0;
}

int32_t nl_fmu_local_open(nl_fmu_t *f, int32_t fmi_version, const char *binary, const char *instance_name,
                    const char *token, const char *resource, uint32_t vr_speed, uint32_t vr_torque)
{
    const char *const *names = fmi_version == 3 ? FMI3_NAMES : FMI2_NAMES;
    int i;
    const double torque_limit = f->torque_limit;
    memset(f, 0, sizeof *f);
    f->torque_limit = torque_limit;
    f->death_fd = -1;
    f->fmi_version = fmi_version;
    f->vr_speed = vr_speed;
    f->vr_torque = vr_torque;
    f->in_call = NL_FMU_CALL_DLOPEN; /* the library's constructors run here: a crash or hang in them is named */
    f->lib = dlopen(binary, RTLD_NOW | RTLD_LOCAL);
    if (f->lib == NULL) {
        const char *why = dlerror();
        keep_message(f, NULL, why != NULL ? why : "dlopen failed");
        return fail(f, NL_FMU_CALL_DLOPEN, 0, 0.0);
    }
    for (i = 0; i < FN_COUNT; ++i) {
        if (names[i] == NULL) {
            continue;
        }
        f->fn[i] = dlsym(f->lib, names[i]);
        if (f->fn[i] == NULL) {
            keep_message(f, NULL, names[i]);
            fail(f, NL_FMU_CALL_DLSYM, 0, 0.0);
            nl_fmu_local_close(f);
            return -1;
        }
    }
    f->in_call = NL_FMU_CALL_INSTANTIATE;
    if (fmi_version == 3) {
        f->instance = FN(f, FN_INSTANTIATE, fmi3InstantiateCoSimulationTYPE *)(
            instance_name, token, resource, fmi3False, fmi3False, fmi3False, fmi3False, NULL, 0, f, fmi3_logger,
            NULL);
    } else {
        fmi2CallbackFunctions *cb = (fmi2CallbackFunctions *)(void *)f->callbacks;
        cb->logger = fmi2_logger;
        cb->allocateMemory = calloc;
        cb->freeMemory = free;
        cb->stepFinished = NULL;
        cb->componentEnvironment = f;
        f->instance = FN(f, FN_INSTANTIATE, fmi2InstantiateTYPE *)(instance_name, fmi2CoSimulation, token, resource,
                                                                   cb, fmi2False, fmi2False);
    }
    if (f->instance == NULL) {
        fail(f, NL_FMU_CALL_INSTANTIATE, 0, 0.0);
        nl_fmu_local_close(f);
        return -1;
    }
    return 0;
}

int32_t nl_fmu_local_enter_init(nl_fmu_t *f, double t0)
{
    f->in_call = NL_FMU_CALL_ENTER_INIT;
    if (f->fmi_version == 3) {
        return check(f, (int)FN(f, FN_ENTER_INIT, fmi3EnterInitializationModeTYPE *)(
                            f->instance, fmi3False, 0.0, t0, fmi3False, 0.0), NL_FMU_CALL_ENTER_INIT, t0);
    }
    f->in_call = NL_FMU_CALL_SETUP;
    if (check(f, (int)FN(f, FN_SETUP, fmi2SetupExperimentTYPE *)(f->instance, fmi2False, 0.0, t0, fmi2False, 0.0),
              NL_FMU_CALL_SETUP, t0) != 0) {
        return -1;
    }
    f->in_call = NL_FMU_CALL_ENTER_INIT;
    return check(f, (int)FN(f, FN_ENTER_INIT, fmi2EnterInitializationModeTYPE *)(f->instance),
                 NL_FMU_CALL_ENTER_INIT, t0);
}

static int32_t set_real(nl_fmu_t *f, uint32_t vr, double value, double t)
{
    int status;
    f->in_call = NL_FMU_CALL_SET;
    if (f->fmi_version == 3) {
        const fmi3ValueReference ref = vr;
        status = (int)FN(f, FN_SET_REAL, fmi3SetFloat64TYPE *)(f->instance, &ref, 1, &value, 1);
    } else {
        const fmi2ValueReference ref = vr;
        status = (int)FN(f, FN_SET_REAL, fmi2SetRealTYPE *)(f->instance, &ref, 1, &value);
    }
    return check(f, status, NL_FMU_CALL_SET, t);
}

static int32_t get_torque(nl_fmu_t *f, double t)
{
    int status;
    double value = 0.0;
    f->in_call = NL_FMU_CALL_GET;
    if (f->fmi_version == 3) {
        const fmi3ValueReference ref = f->vr_torque;
        status = (int)FN(f, FN_GET_REAL, fmi3GetFloat64TYPE *)(f->instance, &ref, 1, &value, 1);
    } else {
        const fmi2ValueReference ref = f->vr_torque;
        status = (int)FN(f, FN_GET_REAL, fmi2GetRealTYPE *)(f->instance, &ref, 1, &value);
    }
    if (check(f, status, NL_FMU_CALL_GET, t) != 0) {
        return -1;
    }
    if (!isfinite(value)) {
        char text[64];
        (void)snprintf(text, sizeof text, "torque output %g", value);
        keep_message(f, NULL, text);
        return fail(f, NL_FMU_CALL_NOT_FINITE, 0, t);
    }
    f->torque = value;
    return 0;
}

int32_t nl_fmu_local_set(nl_fmu_t *f, uint32_t vr, int32_t kind, double value)
{
    int status;
    if (kind == NL_FMU_REAL) {
        return set_real(f, vr, value, 0.0);
    }
    if (kind == NL_FMU_INTEGER && !(value >= (double)INT32_MIN && value <= (double)INT32_MAX)) {
        char text[80];
        (void)snprintf(text, sizeof text, "Integer value %g outside int32", value);
        keep_message(f, NULL, text);
        return fail(f, NL_FMU_CALL_OUT_OF_RANGE, 0, 0.0);
    }
    f->in_call = NL_FMU_CALL_SET;
    if (f->fmi_version == 3) {
        const fmi3ValueReference ref = vr;
        if (kind == NL_FMU_INTEGER) {
            const fmi3Int32 v = (fmi3Int32)value;
            status = (int)FN(f, FN_SET_INTEGER, fmi3SetInt32TYPE *)(f->instance, &ref, 1, &v, 1);
        } else {
            const fmi3Boolean v = value != 0.0 ? fmi3True : fmi3False;
            status = (int)FN(f, FN_SET_BOOLEAN, fmi3SetBooleanTYPE *)(f->instance, &ref, 1, &v, 1);
        }
    } else {
        const fmi2ValueReference ref = vr;
        if (kind == NL_FMU_INTEGER) {
            const fmi2Integer v = (fmi2Integer)value;
            status = (int)FN(f, FN_SET_INTEGER, fmi2SetIntegerTYPE *)(f->instance, &ref, 1, &v);
        } else {
            const fmi2Boolean v = value != 0.0 ? fmi2True : fmi2False;
            status = (int)FN(f, FN_SET_BOOLEAN, fmi2SetBooleanTYPE *)(f->instance, &ref, 1, &v);
        }
    }
    return check(f, status, NL_FMU_CALL_SET, 0.0);
}

int32_t nl_fmu_local_exit_init(nl_fmu_t *f, double speed)
{
    int status;
    if (set_real(f, f->vr_speed, speed, 0.0) != 0) {
        return -1;
    }
    f->in_call = NL_FMU_CALL_EXIT_INIT;
    if (f->fmi_version == 3) {
        status = (int)FN(f, FN_EXIT_INIT, fmi3ExitInitializationModeTYPE *)(f->instance);
    } else {
        status = (int)FN(f, FN_EXIT_INIT, fmi2ExitInitializationModeTYPE *)(f->instance);
    }
    if (check(f, status, NL_FMU_CALL_EXIT_INIT, 0.0) != 0) {
        return -1;
    }
    f->initialised = 1;
    return get_torque(f, 0.0);
}

int32_t nl_fmu_local_period(nl_fmu_t *f, double t, double dt, double speed)
{
    int status;
    if (set_real(f, f->vr_speed, speed, t) != 0 || get_torque(f, t) != 0) {
        return -1;
    }
    f->in_call = NL_FMU_CALL_DO_STEP;
    if (f->fmi_version == 3) {
        fmi3Boolean event = fmi3False;
        fmi3Boolean terminate = fmi3False;
        fmi3Boolean early = fmi3False;
        fmi3Float64 last = t;
        status = (int)FN(f, FN_DO_STEP, fmi3DoStepTYPE *)(f->instance, t, dt, fmi3True, &event, &terminate, &early,
                                                           &last);
        if (status < STATUS_FAILED && terminate) {
            keep_message(f, NULL, "the FMU asked to terminate the simulation");
            return fail(f, NL_FMU_CALL_DO_STEP, status, t);
        }
    } else {
        status = (int)FN(f, FN_DO_STEP, fmi2DoStepTYPE *)(f->instance, t, dt, fmi2True);
    }
    if (check(f, status, NL_FMU_CALL_DO_STEP, t) != 0) {
        return -1;
    }
    f->steps++;
    return 0;
}

void nl_fmu_local_close(nl_fmu_t *f)
{
    if (f->instance != NULL) {
        f->in_call = NL_FMU_CALL_NONE;
        if (f->fmi_version == 3) {
            if (f->initialised) {
                (void)FN(f, FN_TERMINATE, fmi3TerminateTYPE *)(f->instance);
            }
            FN(f, FN_FREE, fmi3FreeInstanceTYPE *)(f->instance);
        } else {
            if (f->initialised) {
                (void)FN(f, FN_TERMINATE, fmi2TerminateTYPE *)(f->instance);
            }
            FN(f, FN_FREE, fmi2FreeInstanceTYPE *)(f->instance);
        }
        f->instance = NULL;
        f->initialised = 0;
    }
    if (f->lib != NULL) {
        dlclose(f->lib);
        f->lib = NULL;
    }
}
