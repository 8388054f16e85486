/* The board link's common control period in C (src/pmsm_hil/sim_target/stm32g4/link.py, BoardLink._period and
 * _take, the Measurement path of `measurement`): the period's inputs (the signal values kept for the Python front
 * end, the mechanical angle unwrapped from the electrical one, the encoder's C read, the overcurrent comparator on
 * TIM1's BKIN), the core run to the period's end (c/board_core.c's hil_core_run), and the period's counters (handler
 * and sleep cycles, exception entries, late compare values, the first late period) into rings that Python reads
 * lazily, with exec_time_ns. The ADC pair's table is filled before the call (c/adc.c, by the caller) and TIM1's
 * duties are read after it (c/tim1.c's outputs function).
 *
 * It declines (0, nothing done) while Python asks for the period (`wake`: frames to or from the host, FDCAN1 or an
 * amplifier changed, an open bridge...), and hands the period back to Python after its run (0 with `resume` set:
 * Python finishes it from the snapshot here) when the run did not end cleanly (a stop code, an error a model holds),
 * something woke Python during it, or TIM1's outputs are off (MOE = 0: the idle legs). The same steps and the same
 * floating-point operations as the Python reference, compared record for record by tests/board/test_native_exc.py.
 * No allocation. It runs without the GIL (a Python model the core calls back takes it through its ctypes callback):
 * the counters' ring is single-producer (here), single-consumer (Python, under the GIL, possibly on another
 * thread: `head` published after its entries, `tail` Python's), and the running sums only grow (Python keeps what
 * it took). */
#define _POSIX_C_SOURCE 199309L
#include <math.h>
#include <stdint.h>
#include <time.h>

#define HIL_PERIOD_RING 1024
#define HIL_PERIOD_HELD 4
/* resume_rc before the core ran: a Python listener raised in the break comparator's call */
#define HIL_PERIOD_BEFORE_RUN (-1)
#define BDTR_MOE (1u << 15)
/* math.pi */
#define HIL_PI 3.141592653589793115997963468544185161590576171875

typedef int (*hil_run_fn)(void *core, int64_t end, int fresh);
typedef void (*hil_break_fn)(void *tim, int level, int64_t now);

typedef struct {
    /* set once by Python */
    void *core;                    /* hil_core_t */
    hil_run_fn run;                /* hil_core_run */
    const uint64_t *count;         /* the core's cycle count */
    const int64_t *sleep_cycles, *handler_cycles, *exc_entries; /* the core's counters */
    void *tim;                     /* TIM1's hil_tim1_t */
    hil_break_fn set_break_pin;    /* hil_tim1_set_break_pin */
    const int64_t *late_writes, *first_late_update;
    const uint32_t *bdtr;
    double *enc_theta_m, *enc_omega_m; /* the encoder timer's C read (null: none) */
    int64_t *enc_period_start;
    const int32_t *held[HIL_PERIOD_HELD]; /* a model in C holds an error when nonzero */
    const int32_t *py_held;        /* a Python callback of a model in C raised (periph_native.Callbacks) */
    int32_t n_held, pole_pairs, has_break, break_active_low, enabled, pad0;
    double hclk_hz, break_limit_a;
    int64_t period_cycles;
    /* shared with Python */
    int32_t wake, resume, resume_rc, has_theta_e, stale, pad1;
    double theta_m, theta_e, omega_m;  /* [rad, rad, rad/s] */
    int64_t period_start;
    double signals[4];             /* i_a, i_b, i_c [A], vdc [V] of the period (stale: not in Python's volts) */
    int64_t sleep0, isr0, entries0, late0;
    int64_t periods, late_first_period, frames_tx, wall_ns;
    int64_t in_c;                  /* periods this function ran to the end */
    int64_t head, tail;            /* the ring's entries written (here) and read (by Python) */
    int64_t isr[HIL_PERIOD_RING], sleep[HIL_PERIOD_RING], late[HIL_PERIOD_RING], entries[HIL_PERIOD_RING];
} hil_board_period_t;

static int64_t now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}

/* Python's float `%` (the result takes the divisor's sign). */
static double py_mod(double x, double y) {
    double r = fmod(x, y);
    if (r != 0.0) {
        if ((y < 0.0) != (r < 0.0)) {
            r += y;
        }
    } else {
        r = copysign(0.0, y);
    }
    return r;
}

static int held(const hil_board_period_t *p) {
    if (*p->py_held) {
        return 1;
    }
    for (int i = 0; i < p->n_held; ++i) {
        if (*p->held[i]) {
            return 1;
        }
    }
    return 0;
}

/* BoardLink._take without the ADC table (filled by the caller); 0, or 1 when a Python listener raised. */
static int take(hil_board_period_t *p, const double *v) {
    const double i_a = v[0], i_b = v[1], i_c = v[2], theta_e = v[3], omega_m = v[4], vdc = v[5];
    const double two_pi = 2.0 * HIL_PI;
    p->signals[0] = i_a;
    p->signals[1] = i_b;
    p->signals[2] = i_c;
    p->signals[3] = vdc;
    p->stale = 1;
    if (p->has_theta_e) {
        const double d = py_mod(theta_e - p->theta_e + HIL_PI, two_pi) - HIL_PI;
        p->theta_m += d / (double)p->pole_pairs;
    } else {
        p->theta_m = theta_e / (double)p->pole_pairs;
    }
    p->theta_e = theta_e;
    p->has_theta_e = 1;
    p->omega_m = omega_m;
    if (p->enc_theta_m) {
        *p->enc_theta_m = p->theta_m;
        *p->enc_omega_m = omega_m;
    }
    if (p->has_break) {
        double over = fabs(i_a);
        if (fabs(i_b) > over) {
            over = fabs(i_b);
        }
        if (fabs(i_c) > over) {
            over = fabs(i_c);
        }
        p->set_break_pin(p->tim, (over > p->break_limit_a) != (p->break_active_low != 0), (int64_t)*p->count);
        return *p->py_held != 0;
    }
    return 0;
}

/* One control period for a Measurement's values v = {i_a, i_b, i_c [A], theta_e [rad], omega_m [rad/s], vdc [V]}:
 * 1 with *exec_time_ns (TIM1's outputs on: the duties are the compare values'), 0 when Python runs it (`resume`
 * set: Python finishes the period begun here). */
int hil_board_period(hil_board_period_t *p, const double *v, int64_t *exec_time_ns) {
    const int64_t tail = __atomic_load_n(&p->tail, __ATOMIC_ACQUIRE);
    if (!p->enabled || p->wake || p->resume || p->head - tail >= HIL_PERIOD_RING) {
        return 0;
    }
    const int64_t t0 = now_ns();
    int rc = HIL_PERIOD_BEFORE_RUN;
    int done = 0;
    if (!take(p, v)) {
        p->sleep0 = *p->sleep_cycles;
        p->isr0 = *p->handler_cycles;
        p->entries0 = *p->exc_entries;
        p->late0 = *p->late_writes;
        const int64_t end = p->period_start + p->period_cycles;
        rc = p->run(p->core, end, 1);
        if (rc == 0 && !held(p) && !p->wake && (*p->bdtr & BDTR_MOE)) {
            p->period_start = end;
            if (p->enc_period_start) {
                *p->enc_period_start = end;
            }
            const int64_t isr = *p->handler_cycles - p->isr0;
            const int64_t k = p->head % HIL_PERIOD_RING;
            p->isr[k] = isr;
            p->sleep[k] = *p->sleep_cycles - p->sleep0;
            p->late[k] = *p->late_writes - p->late0;
            p->entries[k] = *p->exc_entries - p->entries0;
            __atomic_store_n(&p->head, p->head + 1, __ATOMIC_RELEASE); /* after its entries */
            if (p->late_first_period < 0 && *p->first_late_update >= 0) {
                p->late_first_period = p->periods;
            }
            p->periods++;
            p->frames_tx++;
            p->in_c++;
            *exec_time_ns = (int64_t)nearbyint((double)isr / p->hclk_hz * 1e9);
            done = 1;
        }
    }
    if (!done) {
        p->resume = 1;
        p->resume_rc = rc;
    }
    p->wall_ns += now_ns() - t0;
    return done;
}

int64_t hil_board_period_size(void) { return (int64_t)sizeof(hil_board_period_t); }
