/*
 * The load FMU's calls (loop_fmu.h nl_fmu_*): in this process (nl_fmu_local_*), or contained in a process of
 * its own through a mailbox in shared memory. Lock step: the host writes a request and bumps `req`, the FMU's
 * process (nl_fmu_serve) runs it on the nl_fmu_t inside the mailbox and bumps `ack`. Each side spins a little
 * for the other -- the host HOST_SPIN_NS (a running peer answers within a microsecond: a longer spin only keeps
 * a peer sharing its CPU off it), the FMU's process SERVE_SPIN_NS (longer than the host's own work of a period
 * on an idle machine) -- then sleeps on the futex word, woken only when it said it sleeps (`*_waiting`), so a
 * period costs no system call while both have a CPU, and a spinning side's CPU use stays bounded. On a
 * contended CPU a spin only takes the core the other side needs
 * (measured here at load 12 on 2 cores: 2.6k periods/s spinning 50 us, 15.5k blocking at once), so each side
 * counts, over SPIN_WINDOW waits, those whose spin ran out; when more than half did, it blocks at once for
 * SPIN_BACKOFF waits, then tries spinning again (spin_t). The host wakes every WAIT_SLICE_NS to look at the process
 * (death_fd hung up: crashed), the deadline (hung) and nl_fmu_stop (stopped), so it never blocks on the FMU.
 * Also the torque bound of both modes. No allocation.
 */
#define _GNU_SOURCE

#include <errno.h>
#include <linux/futex.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/prctl.h>
#include <sys/syscall.h>
#include <time.h>
#include <unistd.h>

#include "loop_fmu.h"

#define OP_OPEN 1
#define OP_ENTER_INIT 2
#define OP_SET 3
#define OP_EXIT_INIT 4
#define OP_PERIOD 5
#define OP_CLOSE 6

#define HOST_SPIN_NS 5000         /* the host spins this long for an answer before it sleeps [ns] */
#define SERVE_SPIN_NS 20000       /* the FMU's process spins this long for the next request before it sleeps [ns] */
#define SPIN_WINDOW 64            /* waits over which the spins that ran out are counted */
#define SPIN_BACKOFF 1024         /* waits that block at once after a window where most spins ran out */
#define WAIT_SLICE_NS 1000000     /* a sleeping host looks at the process, its deadline and stop this often [ns] */
#define SERVE_SLICE_NS 100000000  /* a sleeping FMU process looks at its parent this often [ns] */
#define NS_PER_S 1000000000LL

/* One side's spin policy (zero: spinning). */
typedef struct {
    int32_t waits, ran_out, block_left, pad;
} spin_t;

typedef struct {
    uint32_t req, ack;            /* futex words: requests sent, requests answered */
    spin_t host_spin, serve_spin; /* each side's own */
    int32_t host_waiting, serve_waiting;
    int32_t op, kind, rc, ready;  /* ready: the FMU's process serves */
    uint32_t vr, vr_speed, vr_torque;
    int32_t fmi_version;
    double t, dt, value;
    char binary[NL_FMU_PATH], name[NL_FMU_PATH], token[NL_FMU_PATH], resource[NL_FMU_PATH];
    nl_fmu_t fmu;                 /* the instance, the FMU process's (its pointers mean nothing here) */
} box_t;

static int64_t now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * NS_PER_S + ts.tv_nsec;
}

static void futex_wait(uint32_t *word, uint32_t value, int64_t ns)
{
    struct timespec ts;
    ts.tv_sec = (time_t)(ns / NS_PER_S);
    ts.tv_nsec = (long)(ns % NS_PER_S);
    (void)syscall(SYS_futex, word, FUTEX_WAIT, value, &ts, NULL, 0); /* shared: the word is in shared memory */
}

static void futex_wake(uint32_t *word)
{
    (void)syscall(SYS_futex, word, FUTEX_WAKE, 1, NULL, NULL, 0);
}

/* How long this wait may spin [ns]: `spin_ns`, or 0 while backing off. */
static int64_t spin_budget(const spin_t *sp, int64_t spin_ns)
{
    return sp->block_left > 0 ? 0 : spin_ns;
}

/* A wait ended; `ran_out`: it had to sleep. */
static void spin_count(spin_t *sp, int ran_out)
{
    if (sp->block_left > 0) {
        sp->block_left--;
        return;
    }
    sp->waits++;
    sp->ran_out += ran_out ? 1 : 0;
    if (sp->waits == SPIN_WINDOW) {
        if (2 * sp->ran_out > SPIN_WINDOW) {
            sp->block_left = SPIN_BACKOFF;
        }
        sp->waits = 0;
        sp->ran_out = 0;
    }
}

static void relax(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
}

static void copy_text(char *dst, const char *src)
{
    (void)snprintf(dst, NL_FMU_PATH, "%s", src != NULL ? src : "");
}

/* --- the host -------------------------------------------------------------------------------------------- */

static int process_ended(const nl_fmu_t *f)
{
    struct pollfd p;
    if (f->death_fd < 0) {
        return 0;
    }
    p.fd = f->death_fd;
    p.events = POLLIN;
    p.revents = 0;
    return poll(&p, 1, 0) > 0 && (p.revents & (POLLIN | POLLHUP | POLLERR)) != 0;
}

/* Wait for answer `seq`: 0 answered, else NL_FMU_ENDED_*. */
static int32_t box_wait(nl_fmu_t *f, box_t *b, uint32_t seq)
{
    const int64_t start = now_ns();
    const int64_t spin_end = start + spin_budget(&b->host_spin, HOST_SPIN_NS);
    const int64_t deadline = start + f->timeout_ns;
    int slept = 0;
    for (;;) {
        uint32_t ack = __atomic_load_n(&b->ack, __ATOMIC_ACQUIRE);
        int64_t now;
        int64_t slice;
        if (ack == seq) {
            spin_count(&b->host_spin, slept);
            return 0;
        }
        now = now_ns();
        if (now < spin_end) {
            relax();
            continue;
        }
        slept = 1;
        if (__atomic_load_n(&f->stop, __ATOMIC_ACQUIRE)) {
            return NL_FMU_ENDED_STOPPED;
        }
        if (process_ended(f)) {
            return __atomic_load_n(&b->ack, __ATOMIC_ACQUIRE) == seq ? 0 : NL_FMU_ENDED_CRASHED;
        }
        if (now >= deadline) {
            return NL_FMU_ENDED_HUNG;
        }
        slice = deadline - now < WAIT_SLICE_NS ? deadline - now : WAIT_SLICE_NS;
        __atomic_store_n(&b->host_waiting, 1, __ATOMIC_SEQ_CST);
        ack = __atomic_load_n(&b->ack, __ATOMIC_SEQ_CST);
        if (ack != seq) {
            futex_wait(&b->ack, ack, slice);
        }
        __atomic_store_n(&b->host_waiting, 0, __ATOMIC_SEQ_CST);
    }
}

/* Send the request prepared in the box (the FMU's process starts on it while this one goes on). */
static void box_send(nl_fmu_t *f, int32_t op)
{
    box_t *b = (box_t *)f->box;
    const uint32_t seq = b->req + 1u; /* the host alone writes req */
    b->op = op;
    __atomic_store_n(&b->req, seq, __ATOMIC_SEQ_CST);
    if (__atomic_load_n(&b->serve_waiting, __ATOMIC_SEQ_CST)) {
        futex_wake(&b->req);
    }
    f->in_flight = 1;
}

/* Wait for the answer to the request box_send sent: its rc, or -1 with f->ended and failed_call (the FMI call the
 * process was in) at time t. */
static int32_t box_finish(nl_fmu_t *f, double t)
{
    box_t *b = (box_t *)f->box;
    int32_t ended;
    f->in_flight = 0;
    ended = box_wait(f, b, b->req);
    f->in_call = b->fmu.in_call;
    if (ended != 0) {
        f->ended = ended;
        if (f->failed_call == NL_FMU_CALL_NONE) {
            f->failed_call = f->in_call;
            f->status = 0;
            f->t_fail = t;
        }
        return -1;
    }
    f->torque = b->fmu.torque;
    f->steps = b->fmu.steps;
    f->warnings = b->fmu.warnings;
    f->initialised = b->fmu.initialised;
    if (b->rc != 0 && f->failed_call == NL_FMU_CALL_NONE) {
        f->failed_call = b->fmu.failed_call;
        f->status = b->fmu.status;
        f->t_fail = b->fmu.t_fail;
        memcpy(f->message, b->fmu.message, sizeof f->message);
        f->message[sizeof f->message - 1u] = '\0';
    }
    return b->rc;
}

/* Send the request prepared in the box and wait for its answer (box_finish). */
static int32_t box_call(nl_fmu_t *f, int32_t op, double t)
{
    if (f->ended != NL_FMU_ENDED_NONE) {
        return -1;
    }
    box_send(f, op);
    return box_finish(f, t);
}

int64_t nl_fmu_box_size(void)
{
    return (int64_t)sizeof(box_t);
}

int32_t nl_fmu_box_attach(nl_fmu_t *f, int32_t shm_fd, int32_t death_fd, int64_t timeout_ns)
{
    void *p = mmap(NULL, sizeof(box_t), PROT_READ | PROT_WRITE, MAP_SHARED, shm_fd, 0);
    if (p == MAP_FAILED) {
        return -1;
    }
    f->box = p;
    f->death_fd = death_fd;
    f->timeout_ns = timeout_ns;
    f->ended = NL_FMU_ENDED_NONE;
    f->stop = 0;
    return 0;
}

int32_t nl_fmu_box_ready(const nl_fmu_t *f)
{
    const box_t *b = (const box_t *)f->box;
    return b != NULL && __atomic_load_n(&b->ready, __ATOMIC_ACQUIRE) ? 1 : 0;
}

void nl_fmu_stop(nl_fmu_t *f)
{
    __atomic_store_n(&f->stop, 1, __ATOMIC_RELEASE);
}

/* |torque| beyond the bound fails the call (the torque kept is the last one within it). */
static int32_t bounded(nl_fmu_t *f, int32_t rc, double previous, double t)
{
    char text[96];
    if (rc != 0 || f->torque_limit <= 0.0 || fabs(f->torque) <= f->torque_limit) {
        return rc;
    }
    (void)snprintf(text, sizeof text, "torque output %g N*m beyond the bound +-%g N*m", f->torque, f->torque_limit);
    f->torque = previous;
    if (f->failed_call == NL_FMU_CALL_NONE) {
        f->failed_call = NL_FMU_CALL_OUT_OF_RANGE;
        f->status = 0;
        f->t_fail = t;
        (void)snprintf(f->message, sizeof f->message, "%s", text);
    }
    return -1;
}

int32_t nl_fmu_open(nl_fmu_t *f, int32_t fmi_version, const char *binary, const char *instance_name,
                    const char *token, const char *resource, uint32_t vr_speed, uint32_t vr_torque)
{
    box_t *b = (box_t *)f->box;
    if (b == NULL) {
        return nl_fmu_local_open(f, fmi_version, binary, instance_name, token, resource, vr_speed, vr_torque);
    }
    f->fmi_version = fmi_version;
    f->vr_speed = vr_speed;
    f->vr_torque = vr_torque;
    b->fmi_version = fmi_version;
    b->vr_speed = vr_speed;
    b->vr_torque = vr_torque;
    copy_text(b->binary, binary);
    copy_text(b->name, instance_name);
    copy_text(b->token, token);
    copy_text(b->resource, resource);
    return box_call(f, OP_OPEN, 0.0);
}

int32_t nl_fmu_enter_init(nl_fmu_t *f, double t0)
{
    box_t *b = (box_t *)f->box;
    if (b == NULL) {
        return nl_fmu_local_enter_init(f, t0);
    }
    b->t = t0;
    return box_call(f, OP_ENTER_INIT, t0);
}

int32_t nl_fmu_set(nl_fmu_t *f, uint32_t vr, int32_t kind, double value)
{
    box_t *b = (box_t *)f->box;
    if (b == NULL) {
        return nl_fmu_local_set(f, vr, kind, value);
    }
    b->vr = vr;
    b->kind = kind;
    b->value = value;
    return box_call(f, OP_SET, 0.0);
}

int32_t nl_fmu_exit_init(nl_fmu_t *f, double speed)
{
    box_t *b = (box_t *)f->box;
    const double previous = f->torque;
    int32_t rc;
    if (b == NULL) {
        rc = nl_fmu_local_exit_init(f, speed);
    } else {
        b->value = speed;
        rc = box_call(f, OP_EXIT_INIT, 0.0);
    }
    return bounded(f, rc, previous, 0.0);
}

int32_t nl_fmu_period_send(nl_fmu_t *f, double t, double dt, double speed)
{
    box_t *b = (box_t *)f->box;
    f->t_sent = t;
    f->torque_before = f->torque;
    if (b == NULL) { /* in this process: the call itself, its rc kept for nl_fmu_period_wait */
        f->rc_sent = nl_fmu_local_period(f, t, dt, speed);
        f->in_flight = 1;
        return 0;
    }
    if (f->ended != NL_FMU_ENDED_NONE) {
        f->rc_sent = -1;
        return -1;
    }
    b->t = t;
    b->dt = dt;
    b->value = speed;
    box_send(f, OP_PERIOD);
    return 0;
}

int32_t nl_fmu_period_wait(nl_fmu_t *f)
{
    int32_t rc;
    if (!f->in_flight) {
        return f->ended != NL_FMU_ENDED_NONE || f->failed_call != NL_FMU_CALL_NONE ? -1 : 0;
    }
    if (f->box == NULL) {
        f->in_flight = 0;
        rc = f->rc_sent;
    } else {
        rc = box_finish(f, f->t_sent);
    }
    return bounded(f, rc, f->torque_before, f->t_sent);
}

int32_t nl_fmu_period(nl_fmu_t *f, double t, double dt, double speed)
{
    if (nl_fmu_period_send(f, t, dt, speed) != 0) {
        return -1;
    }
    return nl_fmu_period_wait(f);
}

void nl_fmu_close(nl_fmu_t *f)
{
    box_t *b = (box_t *)f->box;
    if (b == NULL) {
        f->in_flight = 0;
        nl_fmu_local_close(f);
        return;
    }
    if (f->in_flight && f->ended == NL_FMU_ENDED_NONE) { /* a period sent, never waited for (the run ended) */
        (void)box_finish(f, f->t_sent);
    }
    f->in_flight = 0;
    if (f->ended == NL_FMU_ENDED_NONE) {
        (void)box_call(f, OP_CLOSE, 0.0);
    }
    f->initialised = 0;
    (void)munmap(b, sizeof(box_t));
    f->box = NULL;
}

/* --- the FMU's process ----------------------------------------------------------------------------------- */

/* The next request after `seen` into *req: 1, or 0 once the parent went. */
static int next_request(box_t *b, uint32_t seen, int32_t parent_pid, uint32_t *req)
{
    const int64_t spin_end = now_ns() + spin_budget(&b->serve_spin, SERVE_SPIN_NS);
    int slept = 0;
    for (;;) {
        *req = __atomic_load_n(&b->req, __ATOMIC_ACQUIRE);
        if (*req != seen) {
            spin_count(&b->serve_spin, slept);
            return 1;
        }
        if (now_ns() < spin_end) {
            relax();
            continue;
        }
        slept = 1;
        if (getppid() != parent_pid) {
            return 0;
        }
        __atomic_store_n(&b->serve_waiting, 1, __ATOMIC_SEQ_CST);
        if (__atomic_load_n(&b->req, __ATOMIC_SEQ_CST) == seen) {
            futex_wait(&b->req, seen, SERVE_SLICE_NS);
        }
        __atomic_store_n(&b->serve_waiting, 0, __ATOMIC_SEQ_CST);
    }
}

static int32_t run_request(box_t *b)
{
    nl_fmu_t *f = &b->fmu;
    switch (b->op) {
    case OP_OPEN:
        return nl_fmu_local_open(f, b->fmi_version, b->binary, b->name, b->token, b->resource, b->vr_speed,
                                 b->vr_torque);
    case OP_ENTER_INIT:
        return nl_fmu_local_enter_init(f, b->t);
    case OP_SET:
        return nl_fmu_local_set(f, b->vr, b->kind, b->value);
    case OP_EXIT_INIT:
        return nl_fmu_local_exit_init(f, b->value);
    case OP_PERIOD:
        return nl_fmu_local_period(f, b->t, b->dt, b->value);
    case OP_CLOSE:
        nl_fmu_local_close(f);
        return 0;
    default:
        return -1;
    }
}

int32_t nl_fmu_serve(int32_t shm_fd, int32_t parent_pid)
{
    box_t *b;
    uint32_t seen;
    void *p = mmap(NULL, sizeof(box_t), PROT_READ | PROT_WRITE, MAP_SHARED, shm_fd, 0);
    if (p == MAP_FAILED) {
        return -1;
    }
    b = (box_t *)p;
    (void)prctl(PR_SET_PDEATHSIG, SIGKILL, 0, 0, 0);
    if (getppid() != parent_pid) {
        return 1;
    }
    seen = __atomic_load_n(&b->req, __ATOMIC_ACQUIRE);
    __atomic_store_n(&b->ready, 1, __ATOMIC_RELEASE);
    for (;;) {
        uint32_t req;
        int32_t op;
        if (!next_request(b, seen, parent_pid, &req)) {
            return 1;
        }
        seen = req;
        op = b->op;
        b->rc = run_request(b);
        __atomic_store_n(&b->ack, req, __ATOMIC_SEQ_CST);
        if (__atomic_load_n(&b->host_waiting, __ATOMIC_SEQ_CST)) {
            futex_wake(&b->ack);
        }
        if (op == OP_CLOSE) {
            return 0;
        }
    }
}
