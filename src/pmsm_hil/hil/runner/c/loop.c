/* The native period loop (loop.h): the steps of tests/oracle/closed_loop.py ClosedLoop._run in C. */
#define _POSIX_C_SOURCE 200809L

#include <math.h>
#include <pthread.h>
#include <string.h>

#include "hil_target_core.h"
#include "loop.h"
#include "loop_fmu.h"
#include "loop_frames.h"
#include "loop_rt.h"
#include "loop_stall.h"
#include "machine_kernel.h"
#include "nl_link.h"
#include "pwm_duty.h"

#define SLOT_OWNED_BY_PYTHON 0
#define SLOT_READY 1
#define SLOT_FULL 2
#define PENDING_FINDINGS 16

struct nl_handle {
    nl_config_t cfg;
    nl_slot_t slots[NL_RING];
    nl_result_t res;
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int32_t state[NL_RING];
    int32_t done;
    int32_t stop;
};

/* A command with what the host keeps beside it (closed_loop.py `_pending`, `_pending_split`, `_pending_tref`). */
typedef struct {
    nl_cmd_t cmd;
    uint32_t split[3];
    double tref;
} pending_t;

/* The plant's exact sample at a period start (the kernel's mk_sample_t). */
typedef mk_sample_t sample_t;

typedef struct {
    nl_handle_t *h;
    const nl_config_t *c;
    nl_result_t *r;
    nl_slot_t *slot;
    int32_t slot_i;
    int64_t block;              /* blocks started */
    int32_t noise_i;            /* next noise value of the slot */
    double tap_t;               /* FrameTap t [s] and seq (period index) */
    uint32_t tap_seq;
    int64_t meas_sent;
    /* TargetClient */
    int32_t expected;           /* seq of the last Measurement, -1 before the first */
    int32_t have_reply;
    nl_cmd_t reply;
    int32_t prev_answered;
    nl_cmd_asm_t as;
    int32_t has_fault;
    uint8_t fault_code;
    uint32_t fault_detail;
    int64_t malformed_seen, out_of_seq_seen;
    nl_finding_t pend[PENDING_FINDINGS];
    int32_t n_pend;
    /* the loop */
    pending_t pending;
    pending_t next;
    double speed_ref_rpm;
    int32_t ref_i;
    int32_t inertia;
    int64_t next_start;
    int64_t wait_ns;
    int32_t wait_end;           /* NL_END_RUNNING, or how a lockstep wait ended the run (a host stall, nl_stop) */
    int64_t bus_reply_ns;      /* shared bus: when the last reply was taken (CLOCK_MONOTONIC [ns]), 0: none yet */
} loop_t;

static const double NS_PER_S = 1e9;

uint64_t nl_handle_size(void)
{
    return (uint64_t)sizeof(nl_handle_t);
}

int nl_init(nl_handle_t *h)
{
    int i;
    if (pthread_mutex_init(&h->mu, NULL) != 0) {
        return -1;
    }
    if (pthread_cond_init(&h->cv, NULL) != 0) {
        pthread_mutex_destroy(&h->mu);
        return -1;
    }
    for (i = 0; i < NL_RING; ++i) {
        h->state[i] = SLOT_OWNED_BY_PYTHON;
    }
    h->done = 0;
    h->stop = 0;
    memset(&h->res, 0, sizeof h->res);
    return 0;
}

void nl_destroy(nl_handle_t *h)
{
    pthread_cond_destroy(&h->cv);
    pthread_mutex_destroy(&h->mu);
}

nl_config_t *nl_config(nl_handle_t *h)
{
    return &h->cfg;
}

nl_slot_t *nl_slot(nl_handle_t *h, int32_t i)
{
    return &h->slots[i];
}

const nl_result_t *nl_result(const nl_handle_t *h)
{
    return &h->res;
}

void nl_stop(nl_handle_t *h)
{
    pthread_mutex_lock(&h->mu);
    __atomic_store_n(&h->stop, 1, __ATOMIC_RELEASE);
    pthread_cond_broadcast(&h->cv);
    pthread_mutex_unlock(&h->mu);
}

void nl_release(nl_handle_t *h, int32_t i)
{
    pthread_mutex_lock(&h->mu);
    h->state[i] = SLOT_READY;
    pthread_cond_broadcast(&h->cv);
    pthread_mutex_unlock(&h->mu);
}

static void deadline_in(struct timespec *ts, int64_t timeout_ns)
{
    clock_gettime(CLOCK_REALTIME, ts);
    ts->tv_sec += (time_t)(timeout_ns / 1000000000);
    ts->tv_nsec += (long)(timeout_ns % 1000000000);
    if (ts->tv_nsec >= 1000000000L) {
        ts->tv_sec += 1;
        ts->tv_nsec -= 1000000000L;
    }
}

int nl_wait_full(nl_handle_t *h, int32_t i, int64_t timeout_ns)
{
    struct timespec ts;
    int rc = 0;
    deadline_in(&ts, timeout_ns);
    pthread_mutex_lock(&h->mu);
    while (h->state[i] != SLOT_FULL && !h->done) {
        if (pthread_cond_timedwait(&h->cv, &h->mu, &ts) != 0) {
            break;
        }
    }
    if (h->state[i] == SLOT_FULL) {
        h->state[i] = SLOT_OWNED_BY_PYTHON;
        rc = 1;
    } else if (h->done) {
        rc = -1;
    }
    pthread_mutex_unlock(&h->mu);
    return rc;
}

/* The loop's next slot (waits for Python to hand it back); 0 ok, -1 when stopped while waiting. */
static int take_slot(loop_t *L)
{
    nl_handle_t *h = L->h;
    const int32_t i = (int32_t)(L->block % NL_RING);
    int ready;
    pthread_mutex_lock(&h->mu);
    if (h->state[i] != SLOT_READY) {
        L->r->ring_waits++;
        while (h->state[i] != SLOT_READY && !__atomic_load_n(&h->stop, __ATOMIC_ACQUIRE)) {
            pthread_cond_wait(&h->cv, &h->mu);
        }
    }
    ready = h->state[i] == SLOT_READY;
    pthread_mutex_unlock(&h->mu);
    if (!ready) {
        return -1;
    }
    L->slot_i = i;
    L->slot = &h->slots[i];
    L->slot->n_periods = 0;
    L->slot->n_frames = 0;
    L->slot->n_findings = 0;
    L->slot->n_trace_rows = 0;
    L->noise_i = 0;
    L->block++;
    return 0;
}

static void publish_slot(loop_t *L, int32_t last)
{
    nl_handle_t *h = L->h;
    pthread_mutex_lock(&h->mu);
    h->state[L->slot_i] = SLOT_FULL;
    if (last) {
        h->done = 1;
    }
    pthread_cond_broadcast(&h->cv);
    pthread_mutex_unlock(&h->mu);
    L->slot = NULL;
}

/* --- frames ---------------------------------------------------------------------------------------- */
static void record_frame(loop_t *L, uint8_t direction, const hil_core_frame_t *f)
{
    nl_slot_t *s = L->slot;
    nl_frame_rec_t *rec;
    if (!L->c->outputs.record_frames || s->n_frames >= NL_BLOCK * NL_FRAMES_PER_PERIOD) {
        return;
    }
    rec = &s->frames[s->n_frames++];
    rec->t = L->tap_t;
    rec->seq = L->tap_seq;
    rec->direction = direction;
    rec->arbitration_id = f->id;
    rec->is_fd = f->fd;
    rec->length = f->len;
    memcpy(rec->data, f->data, sizeof rec->data);
}

static void to_target(loop_t *L, const hil_core_frame_t *frames, int n)
{
    const nl_link_t *l = L->c->target_link.link;
    int j;
    for (j = 0; j < n; ++j) {
        L->r->frames_tx++;
        record_frame(L, 0u, &frames[j]);
        (void)l->send(l->ctx, &frames[j]);
    }
}

static void add_pending(loop_t *L, uint8_t rule, uint8_t what, const nl_cmd_t *cmd, int64_t v0, int64_t v1)
{
    nl_finding_t *f;
    if (L->n_pend >= PENDING_FINDINGS) {
        return;
    }
    f = &L->pend[L->n_pend++];
    memset(f, 0, sizeof *f);
    f->rule = rule;
    f->what = what;
    f->v[0] = v0;
    f->v[1] = v1;
    if (cmd != NULL) {
        f->has_cmd = 1u;
        f->cmd_seq = cmd->seq;
        f->n_states = cmd->n_states;
        f->mirror = cmd->mirror;
        memcpy(f->states, cmd->states, sizeof f->states);
        memcpy(f->durations_ns, cmd->durations_ns, sizeof f->durations_ns);
        f->n_duties = cmd->n_duties;
        memcpy(f->duty_raw, cmd->duty_raw, sizeof f->duty_raw);
    }
}

/* TargetClient._on_command. */
static void on_command(loop_t *L, const nl_cmd_t *cmd)
{
    const int32_t seq = cmd->seq;
    if (seq == L->expected) {
        if (!L->have_reply) {
            L->reply = *cmd;
            L->have_reply = 1;
            if (L->c->target_link.shared_bus) {
                L->r->bus_silent_frames = 0;
                L->r->bus_host_silent = 0;
                L->bus_reply_ns = nl_now_ns();
            }
        } else {
            add_pending(L, NL_RULE_SEQUENCE, NL_WHAT_SECOND, cmd, seq, 0);
        }
    } else if (seq == ((L->expected - 1) & 0xFFFF) && !L->prev_answered) {
        L->r->stale_commands++;
        L->prev_answered = 1;
    } else {
        add_pending(L, NL_RULE_SEQUENCE, NL_WHAT_OTHER_SEQ, cmd, seq, L->expected);
    }
}

/* On a shared bus, 1 when frame f can be the target's (loop_frames.h nl_bus_frame); else it is another node's:
 * counted as bus traffic and not decoded. */
static int from_target_node(loop_t *L, const hil_core_frame_t *f)
{
    nl_result_t *r = L->r;
    const int who = nl_bus_frame(f, L->expected, L->have_reply, L->prev_answered, L->c->target_link.controller_id);
    if (who == NL_BUS_TARGET) {
        return 1;
    }
    if (who == NL_BUS_FOREIGN) {
        r->bus_foreign_frames++;
        r->bus_host_silent += nl_host_id(f->id);
    } else {
        r->bus_suspect_frames++;
    }
    r->bus_silent_frames++;
    return 0;
}

/* One frame from the target (TargetClient._drain's body). */
static void take_frame(loop_t *L, const hil_core_frame_t *f)
{
    nl_cmd_t cmd;
    uint8_t code = 0u;
    uint32_t detail = 0u;
    int msg;
    L->r->frames_rx++;
    record_frame(L, 1u, f);
    if (L->c->target_link.shared_bus && !from_target_node(L, f)) {
        return;
    }
    msg = nl_decode(&L->as, f, L->r, &cmd, &code, &detail);
    if (msg == NL_MSG_COMMAND) {
        on_command(L, &cmd);
    } else if (msg == NL_MSG_FAULT && !L->has_fault) {
        L->has_fault = 1;
        L->fault_code = code;
        L->fault_detail = detail;
    }
}

/* Frames until the reply or `deadline_ns`; -1 when the peer closed the link, else 0. */
static int receive_until(loop_t *L, int64_t deadline_ns)
{
    const nl_link_t *l = L->c->target_link.link;
    hil_core_frame_t f;
    int got = 0;
    while (!L->have_reply && (got = l->recv(l->ctx, &f, deadline_ns)) > 0) {
        take_frame(L, &f);
    }
    return got < 0 ? -1 : 0;
}

/* Lockstep: frames until the reply, or until the target had lockstep_timeout_ns to answer. Without a process to
 * observe that is wall time. With one (target_pid), after the first slice the wait goes on in slices and counts
 * only the target's own time (nl_own_time_t, loop_stall.h: the CPU time its process got and the time it slept with
 * nothing to do; an emulated MCU, guest_insns: its executed instructions and QEMU's idle sleep): time the host kept
 * it stopped or off the CPUs is a host stall (counted; the wait goes on, up to stall_limit_ns of wall time:
 * NL_END_HOST_STALL). nl_stop() ends it. */
static void await_lockstep(loop_t *L, int64_t t0)
{
    const nl_config_t *c = L->c;
    const int64_t timeout = c->target_link.lockstep_timeout_ns;
    const int64_t slice = c->target_link.target_pid <= 0 ? timeout
                          : timeout / 4 < NL_STALL_SLICE_NS ? timeout / 4 : NL_STALL_SLICE_NS;
    nl_own_time_t own;
    int watching = 0;
    nl_own_time_start(&own, c->target_link.target_pid, c->target_link.guest_insns, c->target_link.guest_ns_per_insn,
                      slice, t0);
    for (;;) {
        const int64_t left = timeout - own.had_ns;
        int64_t t;
        if (receive_until(L, own.t_prev + (left < slice ? left : slice)) < 0 || L->have_reply) {
            break;
        }
        t = nl_now_ns();
        if (c->target_link.target_pid <= 0) {
            break; /* wall time: one slice, the whole timeout */
        }
        if (nl_own_time_step(&own, t) != 0) {
            break; /* gone (the ending names the crash) or not observable */
        }
        watching = 1;
        if (own.had_ns >= timeout) { /* it had its time: the Command is missing, unless it came while this thread
                                      * was off the CPU between the last receive and now (read what is there) */
            (void)receive_until(L, t);
            break;
        }
        if (__atomic_load_n(&L->h->stop, __ATOMIC_ACQUIRE)) {
            L->wait_end = NL_END_INTERRUPTED;
            break;
        }
        /* past both: the host took the difference */
        if (t - t0 >= c->target_link.stall_limit_ns && t - t0 >= timeout) {
            L->wait_end = NL_END_HOST_STALL;
            L->r->host_stall_wait_ns = t - t0;
            break;
        }
    }
    if (watching) { /* the host's part of a wait the lockstep timeout alone would have ended */
        const int64_t wall = nl_now_ns() - t0;
        const int64_t had = own.had_ns;
        const int64_t lost = wall - (had < wall ? had : wall);
        if (wall > timeout && lost >= slice) {
            L->r->host_stalls++;
            L->r->host_stall_ns += lost;
        }
    }
}

/* ClosedLoop._await_command (TargetClient._drain): what is queued; over a link to another process then frames until
 * the reply or the deadline (the period end in real time, the lockstep timeout else: await_lockstep), then what
 * came with the reply (poll_command drains it all). Over an in-process link (NL_LINK_IN_PROCESS) the target
 * answered inside `send`: what is queued is all there is. */
static void from_target(loop_t *L)
{
    const nl_config_t *c = L->c;
    const nl_link_t *l = c->target_link.link;
    hil_core_frame_t f;
    int64_t t0;
    while (l->recv(l->ctx, &f, 0) > 0) {
        take_frame(L, &f);
    }
    if (L->have_reply || (l->flags & NL_LINK_IN_PROCESS) != 0u) {
        return;
    }
    t0 = nl_now_ns();
    /* real time over a link: period 0 is the synchronising exchange, its Command awaited as in lockstep (a target
     * in another process or on a board wakes from idle and runs its code the first time: cold); the wall clock of
     * the periods starts when it arrives (period(): next_start) */
    if (c->timing.realtime && L->meas_sent > 1) {
        (void)receive_until(L, L->next_start + c->timing.ts_ns);
    } else {
        await_lockstep(L, t0);
    }
    if (L->have_reply) {
        while (l->recv(l->ctx, &f, 0) > 0) {
            take_frame(L, &f);
        }
    }
    L->wait_ns = nl_now_ns() - t0;
}

/* --- plant and sensors --------------------------------------------------------------------------------- */
/* The kernel's exact sample of plant state `state` (fields a kind does not have: NaN). */
static void sample_of(const loop_t *L, const void *state, sample_t *smp)
{
    const nl_config_t *c = L->c;
    int j;
    for (j = 0; j < MK_MAX_LEGS; ++j) {
        smp->i[j] = c->nan;
    }
    smp->i_d = c->nan;
    smp->i_q = c->nan;
    smp->i_x = c->nan;
    smp->i_y = c->nan;
    smp->theta_e = c->nan;
    smp->omega_m = c->nan;
    smp->torque = c->nan;
    c->machine.kernel->sample(c->machine.plant_params, state, smp);
}

static void sample(const loop_t *L, sample_t *smp)
{
    sample_of(L, L->c->machine.plant_state, smp);
}

/* Python's float % (the sign of the divisor). */
static double py_mod(double x, double m)
{
    double r = fmod(x, m);
    if (r != 0.0) {
        if ((m < 0.0) != (r < 0.0)) {
            r += m;
        }
    } else {
        r = copysign(0.0, m);
    }
    return r;
}

/* machine.py _measure3 / _measure6 with sensors.py SensorModel: the measured currents and angle. */
static void measure(loop_t *L, const sample_t *smp, double *cur, double *theta)
{
    const nl_config_t *c = L->c;
    int j;
    for (j = 0; j < c->machine.legs; ++j) {
        cur[j] = smp->i[j];
    }
    *theta = smp->theta_e;
    if (c->sensors.ideal) {
        return;
    }
    if (c->sensors.noise_std != 0.0) {
        for (j = 0; j < c->machine.legs; ++j) {
            cur[j] = cur[j] + L->slot->noise[L->noise_i++];
        }
    }
    if (c->sensors.adc_lsb != 0.0) {
        for (j = 0; j < c->machine.legs; ++j) {
            cur[j] = nearbyint(cur[j] / c->sensors.adc_lsb) * c->sensors.adc_lsb;
        }
    }
    if (c->sensors.enc_step != 0.0) {
        *theta = py_mod(floor(*theta / c->sensors.enc_step) * c->sensors.enc_step, c->sensors.two_pi);
    }
}

/* LoadProfile.value_and_slope at t [s]. */
static void load_at(const nl_config_t *c, double t, double *value, double *slope)
{
    int32_t idx = 0;
    const int32_t n = c->operation.n_load;
    while (idx < n && c->operation.load_t[idx] <= t) {
        idx++;
    }
    *slope = 0.0;
    if (idx == 0) {
        *value = c->operation.load_v[0];
    } else if (idx >= n) {
        *value = c->operation.load_v[n - 1];
    } else {
        const double t0 = c->operation.load_t[idx - 1];
        const double t1 = c->operation.load_t[idx];
        const double v0 = c->operation.load_v[idx - 1];
        const double v1 = c->operation.load_v[idx];
        if (t1 == t0) {
            *value = v1;
        } else {
            const double s = (v1 - v0) / (t1 - t0);
            *value = v0 + s * (t - t0);
            *slope = s;
        }
    }
}

/* LoadProfile.breakpoints_between(t0, t1) as (time, value, slope) triplets; the count, or -count when more
 * than NL_LOAD_BREAKPOINTS. */
static int32_t load_breakpoints(const nl_config_t *c, double t0, double t1, double *bp)
{
    int32_t lo = 0;
    int32_t n_bp = 0;
    int32_t i;
    const int32_t n = c->operation.n_load;
    while (lo < n && c->operation.load_t[lo] <= t0) {
        lo++;
    }
    if (lo >= n || c->operation.load_t[lo] >= t1) {
        return 0;
    }
    for (i = lo; i < n && c->operation.load_t[i] < t1; ++i) {
        if (i > lo && c->operation.load_t[i] == c->operation.load_t[i - 1]) {
            continue; /* sorted(set(...)) */
        }
        if (n_bp < NL_LOAD_BREAKPOINTS) {
            bp[3 * n_bp] = c->operation.load_t[i];
            load_at(c, c->operation.load_t[i], &bp[3 * n_bp + 1], &bp[3 * n_bp + 2]);
        }
        n_bp++;
    }
    return n_bp > NL_LOAD_BREAKPOINTS ? -n_bp : n_bp;
}

/* The load FMU's period (loop_fmu.h): the speed sampled at the period start in, the torque out (held over the
 * period by advance), doStep(t, Ts); 0 ok, NL_PLANT_E_LOAD_FMU when the FMU failed. (Under a dyno the FMU would
 * still step and its torque be recorded, the held speed ignoring it; RunConfig refuses that combination.) */
static int load_fmu_period(loop_t *L, double t, const sample_t *smp)
{
    const nl_config_t *c = L->c;
    return nl_fmu_period(c->operation.load_fmu, t, c->timing.ts_s, smp->omega_m) == 0 ? 0 : NL_PLANT_E_LOAD_FMU;
}

/* ClosedLoop._apply_and_trace: one period with the pending command (mirrored when it is). */
/* The gate sequence of period k as the plant applies it: the pending Command's states (mirrored when asked) or
 * the carrier comparison of its duties (src/pmsm_hil/hil/pwm.py applied_sequence); returns the number of segments. */
static int32_t period_sequence(const loop_t *L, int64_t k, int32_t *states, int64_t *durs)
{
    const nl_config_t *c = L->c;
    const nl_cmd_t *cmd = &L->pending.cmd;
    int32_t n = cmd->n_states;
    int32_t j;
    if (cmd->n_duties != 0u) {
        const int half = !c->timing.pwm_double ? PWM_SINGLE : ((k & 1) == 0 ? PWM_RISING : PWM_FALLING);
        return pwm_duty_sequence(c->machine.legs, cmd->duty_raw, c->timing.ts_ns, half, states, durs);
    }
    for (j = 0; j < n; ++j) {
        states[j] = cmd->states[j];
        durs[j] = cmd->durations_ns[j];
    }
    if (cmd->mirror && n >= 2) {
        for (j = n - 2; j >= 0; --j) {
            states[n] = cmd->states[j];
            durs[n] = cmd->durations_ns[j];
            n++;
        }
    }
    return n;
}

/* The load torque over the next `total_ns` of plant time for the mechanics (inertia mode): torque at the start,
 * slope and breakpoints (into bp); 0, or NL_PLANT_E_BREAKPOINTS. */
static int period_load(loop_t *L, int64_t total_ns, mech_load_t *load, double *bp)
{
    const nl_config_t *c = L->c;
    load->value = 0.0;
    load->slope = 0.0;
    load->bp = bp;
    load->n_bp = 0;
    if (L->inertia && c->operation.load_fmu != NULL) {
        load->value = c->operation.load_fmu->torque; /* load_fmu_period: the FMU's output at the period start, held */
    } else if (L->inertia) {
        const uint64_t t_ns = c->machine.kernel->time_ns(c->machine.plant_state);
        const double t0 = (double)t_ns / NS_PER_S;
        load_at(c, t0, &load->value, &load->slope);
        load->n_bp = load_breakpoints(c, t0, t0 + (double)total_ns * 1e-9, bp);
        if (load->n_bp < 0) {
            L->r->plant_detail = -load->n_bp;
            return NL_PLANT_E_BREAKPOINTS;
        }
    }
    return 0;
}

static int advance(loop_t *L, int64_t k, ge_period_stats_t *st)
{
    const nl_config_t *c = L->c;
    int32_t states[PWM_MAX_SEGMENTS];
    int64_t durs[PWM_MAX_SEGMENTS];
    const int32_t n = period_sequence(L, k, states, durs);
    int32_t j;
    int64_t total = 0;
    mech_load_t load;
    double bp[3 * NL_LOAD_BREAKPOINTS];
    double *trace = c->outputs.plant_trace;
    int rc;
    for (j = 0; j < n; ++j) {
        total += durs[j];
    }
    rc = period_load(L, total, &load, bp);
    if (rc != 0) {
        return rc;
    }
    if (k >= c->operation.n_settle && c->outputs.trace_dt > 0.0) {
        nl_slot_t *s = L->slot;
        if (s->n_trace_rows + c->outputs.trace_cap > s->trace_rows_cap) {
            return MK_E_TRACE_FULL;
        }
        trace = s->trace + s->n_trace_rows * c->outputs.trace_columns;
    }
    rc = c->machine.kernel->advance(c->machine.plant_params, c->machine.plant_state, states, durs, n, &load,
                                    c->outputs.trace_dt,
                            c->outputs.trace_dt > 0.0 ? trace : NULL, c->outputs.trace_cap, st);
    if (rc == 0 && k >= c->operation.n_settle && c->outputs.trace_dt > 0.0) {
        L->slot->n_trace_rows += st->trace_n;
    }
    return rc;
}

/* The Measurement at the firmware's ADC instant, adc_delay_ns after the period start (--adc-delay): a copy of the
 * plant (plant_scratch) advanced through the first adc_delay_ns of the period's gate sequence, then sampled; the
 * plant itself is advanced over the whole period by `advance`, so the records stay the period-start samples. */
static int sample_adc(loop_t *L, int64_t k, sample_t *smp)
{
    const nl_config_t *c = L->c;
    int32_t states[PWM_MAX_SEGMENTS];
    int64_t durs[PWM_MAX_SEGMENTS];
    int32_t n = period_sequence(L, k, states, durs);
    int32_t m = 0;
    int64_t left = c->timing.adc_delay_ns;
    mech_load_t load;
    double bp[3 * NL_LOAD_BREAKPOINTS];
    ge_period_stats_t st;
    int rc;
    while (m < n && left > 0) {
        if (durs[m] >= left) {
            durs[m] = left;
        }
        left -= durs[m];
        ++m;
    }
    rc = period_load(L, c->timing.adc_delay_ns, &load, bp);
    if (rc != 0) {
        return rc;
    }
    memcpy(c->machine.plant_scratch, c->machine.plant_state, (size_t)c->machine.kernel->state_size);
    rc = c->machine.kernel->advance(c->machine.plant_params, c->machine.plant_scratch, states, durs, m, &load, 0.0,
                                    NULL, 0, &st);
    if (rc != 0) {
        return rc;
    }
    sample_of(L, c->machine.plant_scratch, smp);
    return 0;
}

/* --- the period -------------------------------------------------------------------------------------------- */
/* ClosedLoop._follow_reference. */
static void follow_reference(loop_t *L, int64_t k)
{
    const nl_config_t *c = L->c;
    hil_core_frame_t f;
    while (L->ref_i < c->operation.n_ref && c->operation.ref_k[L->ref_i] <= k) {
        const double ref = c->operation.ref_rpm[L->ref_i++];
        if (ref == L->speed_ref_rpm) {
            continue;
        }
        L->speed_ref_rpm = ref;
        nl_encode_setpoint(1u, (uint8_t)c->target_link.mode_speed, ref * c->operation.rpm_to_rad_s,
                           (uint8_t)c->target_link.controller_id, &f);
        to_target(L, &f, 1);
        if (c->operation.dyno) {
            L->inertia = 0;
            c->machine.kernel->hold_speed(c->machine.plant_params, c->machine.plant_state,
                                          ref * c->operation.rpm_to_rad_s);
        }
    }
}

static void add_finding(loop_t *L, int64_t k, const nl_finding_t *f)
{
    nl_slot_t *s = L->slot;
    L->r->violation_count++;
    L->r->by_rule[f->rule]++;
    if (s->n_findings < NL_FINDINGS) {
        s->findings[s->n_findings] = *f;
        s->findings[s->n_findings].period = (uint32_t)k;
        s->n_findings++;
    }
}

/* TargetClient.take_anomalies + ClosedLoop._check_contract: 1 when the reply may be applied. */
static int check_contract(loop_t *L, int64_t k, int have)
{
    const nl_config_t *c = L->c;
    nl_result_t *r = L->r;
    const int64_t malformed = r->dec_bad_length + r->dec_bad_value;
    const int64_t out_of_seq = r->dec_stale + r->dec_duplicate + r->dec_out_of_order + r->dec_mixed_seq;
    int32_t j;
    int ok = have;
    if (malformed != L->malformed_seen) {
        add_pending(L, NL_RULE_FRAME, NL_WHAT_DECODER_FRAME, NULL, malformed - L->malformed_seen, r->dec_bad_length);
        L->pend[L->n_pend - 1].v[2] = r->dec_bad_value;
        L->malformed_seen = malformed;
    }
    if (out_of_seq != L->out_of_seq_seen) {
        add_pending(L, NL_RULE_SEQUENCE, NL_WHAT_DECODER_SEQ, NULL, out_of_seq - L->out_of_seq_seen, r->dec_stale);
        L->pend[L->n_pend - 1].v[2] = r->dec_duplicate;
        L->pend[L->n_pend - 1].v[3] = r->dec_out_of_order;
        L->pend[L->n_pend - 1].v[4] = r->dec_mixed_seq;
        L->out_of_seq_seen = out_of_seq;
    }
    if (L->wait_ns) {
        if (L->wait_ns > r->max_wait_ns) {
            r->max_wait_ns = L->wait_ns;
        }
        L->wait_ns = 0;
    }
    if (have) {
        const nl_cmd_t *cmd = &L->reply;
        int64_t total = 0;
        int bad = 0;
        if (cmd->both_forms) { /* contract.check_command: BOTH_FORMS_ON_WIRE */
            add_pending(L, NL_RULE_DUTY, NL_WHAT_BOTH_FORMS, cmd, 0, 0);
            bad = 1;
        }
        if (cmd->n_duties != 0u) { /* contract.check_duties */
            if (cmd->n_duties != c->machine.legs) {
                add_pending(L, NL_RULE_DUTY, NL_WHAT_DUTY_COUNT, cmd, cmd->n_duties, c->machine.legs);
                bad = 1;
            }
            for (j = 0; !bad && j < cmd->n_duties; ++j) {
                if (cmd->duty_raw[j] > PWM_DUTY_FULL) {
                    add_pending(L, NL_RULE_DUTY, NL_WHAT_DUTY, cmd, j, cmd->duty_raw[j]);
                    bad = 1;
                }
            }
            total = c->timing.ts_ns; /* the carrier fills Ts */
        }
        for (j = 0; j < cmd->n_states; ++j) {
            if (cmd->states[j] > c->machine.max_state) {
                add_pending(L, NL_RULE_STATE_CODE, NL_WHAT_STATE_CODE, cmd, j, cmd->states[j]);
                L->pend[L->n_pend - 1].v[2] = c->machine.max_state;
                bad = 1;
                break;
            }
        }
        if (!bad && cmd->n_duties == 0u) {
            if (cmd->mirror && cmd->n_states >= 2) {
                for (j = 0; j < cmd->n_states - 1; ++j) {
                    total += cmd->durations_ns[j];
                }
                total = 2 * total + cmd->durations_ns[cmd->n_states - 1];
            } else {
                for (j = 0; j < cmd->n_states; ++j) {
                    total += cmd->durations_ns[j];
                }
            }
            if (total != c->timing.ts_ns) {
                add_pending(L, NL_RULE_DURATIONS, NL_WHAT_DURATIONS, cmd, total, c->timing.ts_ns);
                bad = 1;
            }
        }
        ok = !bad;
    } else {
        add_pending(L, NL_RULE_MISSING, NL_WHAT_MISSING, NULL, k & 0xFFFF, 0);
    }
    for (j = 0; j < L->n_pend; ++j) {
        add_finding(L, k, &L->pend[j]);
    }
    L->n_pend = 0;
    return ok;
}

/* ClosedLoop._accept: the pending command of the next period; 1 when the watchdog ends the run. */
static int accept(loop_t *L, int64_t k, int ok)
{
    const nl_config_t *c = L->c;
    const nl_link_t *l = c->target_link.link;
    nl_result_t *r = L->r;
    uint8_t full_miss = 255u;
    if (!ok) {
        r->silent++;
        r->lost_commands++;
        if (c->timing.realtime) {
            r->deadline_misses++;
        }
        if (c->timing.miss_zero) {
            memset(&L->next.cmd, 0, sizeof L->next.cmd);
            L->next.cmd.n_states = 1u;
            L->next.cmd.durations_ns[0] = (uint32_t)c->timing.ts_ns;
        } else {
            L->next.cmd = L->pending.cmd;
        }
        memcpy(L->next.split, L->pending.split, sizeof L->next.split);
        L->next.tref = L->pending.tref;
        return r->silent >= c->target_link.watchdog_periods;
    }
    r->silent = 0;
    L->next.cmd = L->reply;
    memset(L->next.split, 0, sizeof L->next.split);
    L->next.tref = c->nan;
    if (l->diag != NULL && l->diag(l->ctx, L->next.split, &L->next.tref, &full_miss)) { /* an in-process target */
        if (full_miss != 255u && k >= c->operation.n_settle) {
            r->candidate_checked++;
            r->candidate_misses += full_miss;
        }
    } else if (c->target_link.sil_debug != NULL) { /* a SIL target in its own process: its slot before the Command */
        const volatile nl_sil_debug_t *d = c->target_link.sil_debug;
        if (d->steps > 0u) {
            L->next.tref = (double)d->torque_ref;
        }
    } /* another process: no split, no torque reference crosses the link */
    return 0;
}

/* ClosedLoop._record. */
static void record(loop_t *L, double t, int64_t k, const sample_t *smp, const ge_period_stats_t *st, int missed,
                   double load_t)
{
    const nl_config_t *c = L->c;
    const pending_t *p = &L->pending;
    nl_period_t *rec = &L->slot->periods[L->slot->n_periods++];
    int j;
    rec->t = t;
    rec->seq = (uint32_t)k;
    rec->i_a = smp->i[0];
    rec->i_b = smp->i[1];
    rec->i_c = smp->i[2];
    rec->i_d = smp->i_d;
    rec->i_q = smp->i_q;
    rec->torque = smp->torque;
    rec->omega_m = smp->omega_m;
    rec->theta_e = smp->theta_e;
    rec->torque_ref = p->tref;
    rec->speed_ref = L->speed_ref_rpm * c->operation.rpm_to_rad_s;
    rec->load_torque = load_t;
    rec->n_states = p->cmd.n_states;
    for (j = 0; j < 3; ++j) {
        rec->states[j] = j < p->cmd.n_states ? p->cmd.states[j] : 0u;
        rec->durations_ns[j] = j < p->cmd.n_states ? p->cmd.durations_ns[j] : 0u;
        rec->exec_split_ns[j] = p->split[j];
    }
    rec->vector_id = p->cmd.vector_id;
    rec->candidates = p->cmd.candidates;
    rec->exec_time_ns = p->cmd.exec_time_ns;
    rec->leg_transitions = (uint16_t)st->leg_transitions;
    rec->boundary_transitions = (uint16_t)st->boundary_transitions;
    rec->narrow_pulses = (uint16_t)st->narrow_pulses;
    rec->late = 0u;
    rec->missed = (uint8_t)(missed ? 1u : 0u);
    rec->narrow_pulses_gated = (uint16_t)st->narrow_pulses_gated;
    rec->mirror = p->cmd.mirror;
    /* the second winding set (NaN where the machine has none: the sample's fill) */
    rec->i_u = smp->i[3];
    rec->i_v = smp->i[4];
    rec->i_w = smp->i[5];
    rec->i_x = smp->i_x;
    rec->i_y = smp->i_y;
    rec->n_duties = p->cmd.n_duties;
    for (j = 0; j < 6; ++j) {
        rec->duties[j] = j < p->cmd.n_duties ? (double)p->cmd.duty_raw[j] / (double)PWM_DUTY_FULL : c->nan;
    }
    L->r->completed_periods = k + 1;
    L->pending = L->next;
}

/* ClosedLoop._check_end (the final-period trip check stays in Python): 1 to stop. */
static int check_end(loop_t *L, int64_t k, const sample_t *smp, const ge_period_stats_t *st)
{
    const nl_config_t *c = L->c;
    const double i_trip = c->machine.i_trip;
    int j;
    int trip = 0;
    if (L->has_fault) {
        L->r->end = NL_END_FAULT;
        L->r->fault_code = L->fault_code;
        L->r->fault_detail = L->fault_detail;
        return 1;
    }
    for (j = 0; j < c->machine.legs; ++j) {
        if (fabs(smp->i[j]) > i_trip) {
            trip = 1;
        }
    }
    if (fabs(smp->omega_m) > c->machine.w_trip || st->peak_current > i_trip) {
        trip = 1;
    }
    if (trip) {
        L->r->end = NL_END_TRIP;
        L->r->peak_current = st->peak_current;
        return 1;
    }
    (void)k;
    return 0;
}

/* Measurement k to the target (TargetClient.send_measurement); 0 ok, -1 when the codec refused a value. */
static int send_measurement(loop_t *L, int64_t k, double t, const sample_t *smp)
{
    const nl_config_t *c = L->c;
    hil_core_frame_t frames[3];
    double cur[6];
    double theta;
    int n = 0;
    const uint16_t seq = (uint16_t)(k & 0xFFFF);
    measure(L, smp, cur, &theta);
    if (nl_encode_meas(c, seq, cur, theta, smp->omega_m, frames, &n, &L->r->encode_field, &L->r->encode_value)
        != 0) {
        return -1;
    }
    L->tap_t = t;
    L->tap_seq = (uint32_t)k;
    if (c->target_link.link->period != NULL) {
        c->target_link.link->period(c->target_link.link->ctx, t);
    }
    if (L->expected >= 0) {
        L->prev_answered = L->have_reply;
    }
    L->expected = seq;
    L->have_reply = 0;
    L->meas_sent++;
    to_target(L, frames, n);
    return 0;
}

static void loop_init(loop_t *L, nl_handle_t *h)
{
    const nl_config_t *c = &h->cfg;
    memset(L, 0, sizeof *L);
    L->h = h;
    L->c = c;
    L->r = &h->res;
    L->expected = -1;
    L->prev_answered = 1;
    L->as.states.held_seq = -1;
    L->as.duty.held_seq = -1;
    L->has_fault = c->target_link.fault_pending;
    L->fault_code = c->target_link.fault_code_in;
    L->fault_detail = c->target_link.fault_detail_in;
    if (c->target_link.first_n_duties > 0 && c->target_link.first_n_duties <= 6) {
        L->pending.cmd.n_duties = (uint8_t)c->target_link.first_n_duties;
        memcpy(L->pending.cmd.duty_raw, c->target_link.first_duty_raw, sizeof L->pending.cmd.duty_raw);
    } else {
        L->pending.cmd.n_states = 1u;
        L->pending.cmd.durations_ns[0] = (uint32_t)c->timing.ts_ns;
    }
    L->pending.tref = c->nan;
    L->speed_ref_rpm = c->operation.n_ref > 0 ? c->operation.ref_rpm[0] : 0.0;
    L->ref_i = c->operation.n_ref > 0 ? 1 : 0;
    L->inertia = c->operation.inertia;
}

/* One period k; returns NL_END_RUNNING or the ending. */
static int32_t period(loop_t *L, int64_t k)
{
    const nl_config_t *c = L->c;
    nl_result_t *r = L->r;
    const double t = (double)k * c->timing.ts_s;
    sample_t smp;
    ge_period_stats_t st;
    double load_t;
    double unused_slope;
    int ok;
    int watchdog;
    int rc;
    if (c->timing.realtime) {
        const int64_t now = nl_wait_until(L->next_start, c->timing.spin_ns);
        const int64_t late = now - L->next_start;
        L->slot->lateness_ns[L->slot->n_periods] = late;
        nl_late_count(r, late);
        if (late > c->timing.overrun_ns) {
            r->overruns++;
        }
    }
    follow_reference(L, k);
    sample(L, &smp);
    rc = 0;
    if (c->timing.adc_delay_ns > 0) { /* the firmware's ADC samples later in the period than its start */
        sample_t adc;
        /* the period's load first: the copy sees it */
        rc = c->operation.load_fmu != NULL ? load_fmu_period(L, t, &smp) : 0;
        if (rc == 0) {
            rc = sample_adc(L, k, &adc);
        }
        if (rc != 0) {
            r->plant_rc = rc;
            return NL_END_PLANT_ERROR;
        }
        if (send_measurement(L, k, t, &adc) != 0) {
            return NL_END_ENCODE_ERROR;
        }
    } else { /* the load FMU's period is sent first: contained, its process steps while the target does */
        const int sent = c->operation.load_fmu != NULL
                             ? nl_fmu_period_send(c->operation.load_fmu, t, c->timing.ts_s, smp.omega_m) : 0;
        if (send_measurement(L, k, t, &smp) != 0) {
            return NL_END_ENCODE_ERROR;
        }
        if (c->operation.load_fmu != NULL && (sent != 0 || nl_fmu_period_wait(c->operation.load_fmu) != 0)) {
            rc = NL_PLANT_E_LOAD_FMU;
        }
    }
    if (rc == 0) {
        rc = advance(L, k, &st);
    }
    if (rc != 0) {
        r->plant_rc = rc;
        return NL_END_PLANT_ERROR;
    }
    from_target(L);
    if (L->wait_end != NL_END_RUNNING) { /* the wait for this period's Command ended the run, no verdict on it */
        return L->wait_end;
    }
    /* in process nothing more will come: real time waits the period out */
    if (!L->have_reply && c->timing.realtime && (c->target_link.link->flags & NL_LINK_IN_PROCESS) != 0u) {
        const int64_t t0 = nl_now_ns();
        const int64_t now = nl_wait_until(L->next_start + c->timing.ts_ns, 0);
        L->wait_ns = now - t0;
    }
    ok = check_contract(L, k, L->have_reply);
    watchdog = accept(L, k, ok);
    if (c->operation.load_fmu != NULL) {
        load_t = c->operation.load_fmu->torque;
    } else {
        load_at(c, t, &load_t, &unused_slope);
    }
    record(L, t, k, &smp, &st, !ok, load_t); /* missed: no Command applied (none, or one breaking the contract) */
    if (r->violation_count > c->target_link.tolerate) {
        return NL_END_VIOLATION;
    }
    if (watchdog) {
        return NL_END_WATCHDOG;
    }
    L->next_start += c->timing.ts_ns;
    /* over a link to another process the synchronising exchange is done: real time starts now */
    if (k == 0 && c->timing.realtime && (c->target_link.link->flags & NL_LINK_IN_PROCESS) == 0u) {
        const int64_t now = nl_now_ns();
        r->sync_ns = now - (L->next_start - c->timing.ts_ns);
        if (now > L->next_start) {
            L->next_start = now;
        }
    }
    if ((k + 1) % NL_BLOCK == 0) {
        publish_slot(L, 0);
    }
    if (check_end(L, k, &smp, &st)) {
        return r->end;
    }
    return NL_END_RUNNING;
}

/* Phase currents each Measurement format carries (index: NL_MEAS_*). */
static const int32_t MEAS_CURRENTS[NL_MEAS_FORMATS] = {3, 6};

/* The machine kernel can run in this loop: a table of this ABI whose legs the Measurement format carries. */
static int kernel_fits(const nl_config_t *c)
{
    const mk_kernel_t *k = c->machine.kernel;
    if (k == NULL || k->abi != MK_ABI_VERSION || k->legs != c->machine.legs || k->legs < 1 || k->legs > MK_MAX_LEGS) {
        return 0;
    }
    if (c->machine.plant_params == NULL || c->machine.plant_state == NULL || k->advance == NULL || k->sample == NULL
        || k->hold_speed == NULL || k->time_ns == NULL) {
        return 0;
    }
    const int32_t format = c->target_link.codec.meas_format;
    return format >= 0 && format < NL_MEAS_FORMATS && MEAS_CURRENTS[format] == k->legs;
}

void nl_run(nl_handle_t *h)
{
    loop_t L;
    nl_rt_saved_t saved;
    int64_t k;
    int32_t end = NL_END_COMPLETED;
    int64_t t_start;
    loop_init(&L, h);
    if (!kernel_fits(&h->cfg)) {
        h->res.plant_rc = NL_PLANT_E_KERNEL;
        h->res.end = NL_END_PLANT_ERROR;
        h->res.end_period = 0;
        pthread_mutex_lock(&h->mu);
        h->done = 1;
        pthread_cond_broadcast(&h->cv);
        pthread_mutex_unlock(&h->mu);
        return;
    }
    if (h->cfg.timing.realtime || h->cfg.timing.rt_priority > 0 || h->cfg.timing.cpu >= 0
        || h->cfg.timing.lock_memory) {
        nl_rt_setup(&h->cfg.timing, &h->res, &saved);
    } else {
        memset(&saved, 0, sizeof saved);
    }
    t_start = nl_now_ns();
    L.next_start = t_start;
    h->res.sync_ns = -1;
    for (k = 0; k < h->cfg.operation.n_total; ++k) {
        int32_t e;
        if (__atomic_load_n(&h->stop, __ATOMIC_ACQUIRE) || (L.slot == NULL && take_slot(&L) != 0)) {
            end = NL_END_INTERRUPTED;
            h->res.end_period = k;
            break;
        }
        e = period(&L, k);
        if (e != NL_END_RUNNING) {
            end = e;
            h->res.end_period = k;
            break;
        }
    }
    h->res.wall_ns = nl_now_ns() - t_start;
    h->res.bus_silent_ns = nl_now_ns() - (L.bus_reply_ns > 0 ? L.bus_reply_ns : t_start);
    h->res.speed_ref_rpm = L.speed_ref_rpm;
    h->res.tap_t = L.tap_t;
    h->res.tap_seq = L.tap_seq;
    h->res.end = end;
    nl_rt_restore(&saved);
    if (L.slot != NULL) {
        publish_slot(&L, 1);
    } else {
        pthread_mutex_lock(&h->mu);
        h->done = 1;
        pthread_cond_broadcast(&h->cv);
        pthread_mutex_unlock(&h->mu);
    }
}
