/* Real-time support of the native loop (loop_rt.h). Linux: sched_setscheduler / sched_setaffinity act on the
 * calling thread when given pid 0. */
#define _GNU_SOURCE

#include <errno.h>
#include <stddef.h>
#include <stdint.h>
#include <sched.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>

#include "loop_rt.h"

int64_t nl_now_ns(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + (int64_t)ts.tv_nsec;
}

int64_t nl_wait_until(int64_t deadline_ns, int64_t spin_ns)
{
    int64_t now = nl_now_ns();
    if (deadline_ns - now > spin_ns) {
        const int64_t wake = deadline_ns - spin_ns;
        struct timespec ts;
        ts.tv_sec = (time_t)(wake / 1000000000);
        ts.tv_nsec = (long)(wake % 1000000000);
        while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR) {
        }
        now = nl_now_ns();
    }
    while (now < deadline_ns) {
        now = nl_now_ns();
    }
    return now;
}

/* Touch NL_STACK_PREFAULT bytes of the calling thread's stack below this frame, so that the loop's calls do not
 * fault them in during the run (its memory is locked). */
static void __attribute__((noinline)) prefault_stack(void)
{
    volatile uint8_t stack[NL_STACK_PREFAULT];
    for (size_t i = 0; i < sizeof stack; i += 4096) {
        stack[i] = 0;
    }
}

void nl_rt_setup(const nl_timing_cfg_t *cfg, nl_result_t *r, nl_rt_saved_t *saved)
{
    memset(saved, 0, sizeof *saved);
    if (cfg->lock_memory) {
        int rc = -1;
#ifdef MCL_ONFAULT
        /* pages resident now stay resident; the others are locked when first touched (a minor fault then), so
         * a large process (a pytest worker, gigabytes mapped) is not populated whole: the loop's own memory (its
         * handle with the record slots, the plant's state) is written before the run, and its stack below */
        rc = mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT);
        if (rc != 0 && errno != EINVAL) {
            r->rt_mlock_errno = errno;
        }
#endif
        if (rc != 0 && r->rt_mlock_errno == 0) {  /* a kernel before 4.4: every mapped page populated and locked */
            rc = mlockall(MCL_CURRENT | MCL_FUTURE);
            if (rc != 0) {
                r->rt_mlock_errno = errno;
            }
        }
        if (rc == 0) {
            saved->locked = 1;
            prefault_stack();
        }
    }
    if (cfg->cpu >= 0) {
        cpu_set_t old;
        cpu_set_t want;
        CPU_ZERO(&old);
        if (sched_getaffinity(0, sizeof old, &old) != 0) {
            r->rt_affinity_errno = errno;
        } else {
            CPU_ZERO(&want);
            CPU_SET((size_t)cfg->cpu, &want);
            if (sched_setaffinity(0, sizeof want, &want) == 0) {
                saved->affinity_set = 1;
                memcpy(saved->old_mask, &old, sizeof old < sizeof saved->old_mask ? sizeof old
                                                                                  : sizeof saved->old_mask);
            } else {
                r->rt_affinity_errno = errno;
            }
        }
    }
    if (cfg->rt_priority > 0) {
        struct sched_param sp;
        saved->old_policy = sched_getscheduler(0);
        (void)sched_getparam(0, &sp);
        saved->old_priority = sp.sched_priority;
        sp.sched_priority = cfg->rt_priority;
        if (sched_setscheduler(0, SCHED_FIFO, &sp) == 0) {
            saved->sched_set = 1;
        } else {
            r->rt_sched_errno = errno;
        }
    }
}

void nl_late_count(nl_result_t *r, int64_t late_ns)
{
    int64_t bin = late_ns / 1000;
    if (bin < 0) {
        bin = 0;
    } else if (bin >= NL_LATE_BINS) {
        bin = NL_LATE_BINS - 1;
    }
    r->late_hist[bin]++;
    if (late_ns > r->late_max_ns) {
        r->late_max_ns = late_ns;
    }
}

void nl_rt_restore(const nl_rt_saved_t *saved)
{
    if (saved->sched_set) {
        struct sched_param sp;
        sp.sched_priority = saved->old_priority;
        (void)sched_setscheduler(0, saved->old_policy, &sp);
    }
    if (saved->affinity_set) {
        cpu_set_t old;
        memcpy(&old, saved->old_mask, sizeof old < sizeof saved->old_mask ? sizeof old : sizeof saved->old_mask);
        (void)sched_setaffinity(0, sizeof old, &old);
    }
    if (saved->locked) {
        (void)munlockall();
    }
}

int32_t nl_gap_probe(int64_t duration_ns, int64_t gap_ns, int32_t cpu, int32_t rt_priority, nl_gap_probe_t *out)
{
    nl_timing_cfg_t cfg;
    nl_result_t r;
    nl_rt_saved_t saved;
    int64_t last;
    int64_t end;
    int32_t refused;
    memset(&cfg, 0, sizeof cfg);
    memset(&r, 0, sizeof r);
    memset(out, 0, sizeof *out);
    cfg.cpu = cpu;
    cfg.rt_priority = rt_priority;
    cfg.lock_memory = 1;
    nl_rt_setup(&cfg, &r, &saved);
    refused = r.rt_sched_errno ? r.rt_sched_errno : (r.rt_affinity_errno ? r.rt_affinity_errno : 0);
    last = nl_now_ns();
    end = last + duration_ns;
    while (last < end) {
        const int64_t t = nl_now_ns();
        const int64_t d = t - last;
        const int64_t bin = d / 1000;
        out->reads++;
        out->hist[bin < NL_LATE_BINS ? bin : NL_LATE_BINS - 1]++;
        if (d > 10000) {
            out->gaps_10us++;
        }
        if (d > gap_ns) {
            out->gaps++;
            out->lost_ns += d;
        }
        if (d > out->max_gap_ns) {
            out->max_gap_ns = d;
        }
        last = t;
    }
    nl_rt_restore(&saved);
    return refused;
}
