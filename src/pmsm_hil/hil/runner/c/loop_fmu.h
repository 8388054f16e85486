/*
 * The mechanical load as an FMU (FMI 2.0 or 3.0 Co-Simulation) in the C period loop: the FMU's shared
 * library is opened with dlopen, instantiated and initialised before the run (from Python, through cffi), and
 * each period the loop sets its speed input [rad/s, mechanical] at the period start, reads its torque output
 * [N*m] (held over the period) and calls doStep(t, Ts) -- the FMU's own C API, nothing of Python per period.
 * Nothing is allocated per period; the struct is the caller's.
 *
 * Contained (the default, loop_fmu_box.c): the FMU runs in a process of its own (nl_fmu_serve) and each nl_fmu_*
 * call of this process is a request in a mailbox both map (a lock-step exchange: a short spin, then a futex
 * wait); a crash or exit of that process, a call longer than timeout_ns or nl_fmu_stop ends the call at once
 * with `ended` set, so nothing the FMU does can take or hold the loop. A period can be sent and awaited apart
 * (nl_fmu_period_send / _wait), so that the loop does other work while the FMU's process steps. Without
 * nl_fmu_box_attach the FMU's functions are called in this process (`--load-fmu-isolation none`: unprotected).
 */
#ifndef HIL_NATIVE_LOOP_FMU_H
#define HIL_NATIVE_LOOP_FMU_H

#include <stdint.h>

#define NL_FMU_MESSAGE 512       /* bytes of the last message the FMU logged (or of our own error) */

/* Value kinds --load-fmu-set writes (nl_fmu_set). */
#define NL_FMU_REAL 0            /* fmi2Real / fmi3Float64 */
#define NL_FMU_INTEGER 1         /* fmi2Integer / fmi3Int32 */
#define NL_FMU_BOOLEAN 2         /* fmi2Boolean / fmi3Boolean */

/* The FMI call that failed (nl_fmu_t.failed_call). */
#define NL_FMU_CALL_NONE 0
#define NL_FMU_CALL_DLOPEN 1
#define NL_FMU_CALL_DLSYM 2
#define NL_FMU_CALL_INSTANTIATE 3
#define NL_FMU_CALL_SETUP 4      /* fmi2SetupExperiment */
#define NL_FMU_CALL_ENTER_INIT 5
#define NL_FMU_CALL_EXIT_INIT 6
#define NL_FMU_CALL_SET 7        /* a parameter or the speed input */
#define NL_FMU_CALL_GET 8        /* the torque output */
#define NL_FMU_CALL_DO_STEP 9
#define NL_FMU_CALL_NOT_FINITE 10 /* the torque output is NaN or infinite */
#define NL_FMU_CALL_OUT_OF_RANGE 11 /* |torque output| > torque_limit, or an Integer value outside int32 */

/* How the FMU's process ended a call (nl_fmu_t.ended; failed_call then names the FMI call it was in). */
#define NL_FMU_ENDED_NONE 0
#define NL_FMU_ENDED_CRASHED 1   /* the process died (a signal or an exit) */
#define NL_FMU_ENDED_HUNG 2      /* no answer within timeout_ns */
#define NL_FMU_ENDED_STOPPED 3   /* nl_fmu_stop while waiting (Ctrl-C, SIGTERM) */

/* The bytes of a string the FMU's process is handed (binary path, instance name, token, resource path). */
#define NL_FMU_PATH 4096

typedef struct nl_fmu {
    int32_t fmi_version;         /* 2 or 3 */
    uint32_t vr_speed, vr_torque;
    void *lib;                   /* dlopen handle */
    void *instance;              /* fmi2Component / fmi3Instance */
    void *fn[12];                /* the FMU's functions (loop_fmu.c's FN_* order) */
    void *callbacks[8];          /* fmi2CallbackFunctions (FMI 2 keeps a pointer to it) */
    int32_t initialised;
    double torque;               /* the output read at the start of the last period [N*m] */
    int64_t steps;               /* doStep calls that succeeded */
    int64_t warnings;            /* calls that returned a warning */
    int32_t failed_call;         /* NL_FMU_CALL_* of the first failure */
    int32_t status;              /* its FMI status (fmi2Status / fmi3Status value) */
    double t_fail;               /* communication point of the failure [s] */
    char message[NL_FMU_MESSAGE];/* the last error or warning the FMU logged, or the dlopen/dlsym error */
    int32_t in_call;             /* NL_FMU_CALL_* being made (set before each FMI call): where a crash happened */
    /* Containment (loop_fmu_box.c), set before nl_fmu_open and kept by it. */
    double torque_limit;         /* |torque output| above this [N*m] fails the call (0: no limit) */
    void *box;                   /* the mailbox shared with the FMU's process (NULL: the FMU runs in this one) */
    int32_t death_fd;            /* readable / hung up once that process has ended */
    int32_t ended;               /* NL_FMU_ENDED_* */
    int64_t timeout_ns;          /* wall time a call may take [ns] */
    int32_t stop;                /* nl_fmu_stop: a wait ends at once */
    /* A period sent (nl_fmu_period_send) and not yet waited for (nl_fmu_period_wait). */
    int32_t in_flight;
    int32_t rc_sent;             /* in this process: the period's rc, made at once */
    double t_sent;               /* its time [s] */
    double torque_before;        /* the torque output before it [N*m] (kept when the new one is out of bounds) */
} nl_fmu_t;

/* Open the FMU's binary and instantiate it (Co-Simulation); 0 ok, -1 with failed_call and message. `resource`:
 * FMI 2 the resources folder as a file:// URI, FMI 3 its path with a trailing '/'. */
int32_t nl_fmu_open(nl_fmu_t *f, int32_t fmi_version, const char *binary, const char *instance_name,
                    const char *token, const char *resource, uint32_t vr_speed, uint32_t vr_torque);
/* Enter initialisation mode at t0 [s] (FMI 2: fmi2SetupExperiment first); 0 ok. */
int32_t nl_fmu_enter_init(nl_fmu_t *f, double t0);
/* Write a parameter (in initialisation mode): kind NL_FMU_*; 0 ok. */
int32_t nl_fmu_set(nl_fmu_t *f, uint32_t vr, int32_t kind, double value);
/* Set the speed input [rad/s], leave initialisation mode and read the torque output [N*m] (f->torque); 0 ok. */
int32_t nl_fmu_exit_init(nl_fmu_t *f, double speed);
/* One period: speed [rad/s] at its start t [s], the torque output read (f->torque, held over the period),
 * then doStep(t, dt); 0 ok, -1 with failed_call, status, t_fail and message. */
int32_t nl_fmu_period(nl_fmu_t *f, double t, double dt, double speed);
/* nl_fmu_period in two halves: send the period's request (contained: the FMU's process starts on it while the
 * caller goes on, e.g. with the target's step), then wait for its answer; nl_fmu_period_wait returns what
 * nl_fmu_period would have. In this process the send makes the call itself. 0 / -1 as nl_fmu_period. */
int32_t nl_fmu_period_send(nl_fmu_t *f, double t, double dt, double speed);
int32_t nl_fmu_period_wait(nl_fmu_t *f);
/* Terminate (when initialised), free the instance and close the library; safe to call twice. Contained: asks
 * the FMU's process to do so (unless it ended) and unmaps the mailbox; the process then exits. */
void nl_fmu_close(nl_fmu_t *f);

/* The same calls on an FMU in this process (what nl_fmu_serve runs; nl_fmu_* without a box). */
int32_t nl_fmu_local_open(nl_fmu_t *f, int32_t fmi_version, const char *binary, const char *instance_name,
                          const char *token, const char *resource, uint32_t vr_speed, uint32_t vr_torque);
int32_t nl_fmu_local_enter_init(nl_fmu_t *f, double t0);
int32_t nl_fmu_local_set(nl_fmu_t *f, uint32_t vr, int32_t kind, double value);
int32_t nl_fmu_local_exit_init(nl_fmu_t *f, double speed);
int32_t nl_fmu_local_period(nl_fmu_t *f, double t, double dt, double speed);
void nl_fmu_local_close(nl_fmu_t *f);

/* Bytes of the mailbox (the shared memory file's size). */
int64_t nl_fmu_box_size(void);
/* Map the mailbox of shared memory file `shm_fd` (nl_fmu_box_size bytes, zeroed) into f, the FMU's process
 * serving it and `death_fd` hanging up when it ends; each call then waits at most timeout_ns. Before nl_fmu_open;
 * 0 ok, -1 (errno). */
int32_t nl_fmu_box_attach(nl_fmu_t *f, int32_t shm_fd, int32_t death_fd, int64_t timeout_ns);
/* 1 once the FMU's process serves the mailbox (before that, a call would wait for its start-up). */
int32_t nl_fmu_box_ready(const nl_fmu_t *f);
/* End a wait for the FMU's process at once (NL_FMU_ENDED_STOPPED); any thread, any time. */
void nl_fmu_stop(nl_fmu_t *f);
/* The FMU's process: serve the mailbox of `shm_fd` until nl_fmu_close's request, or the exit of parent_pid
 * (also SIGKILL on it, PR_SET_PDEATHSIG); 0 closed, 1 the parent went, -1 mapping failed. */
int32_t nl_fmu_serve(int32_t shm_fd, int32_t parent_pid);

#endif
