/*
 * Real-time support of the native loop: CLOCK_MONOTONIC time, waiting for an absolute deadline (sleep until
 * a bounded spin window before it, then busy-wait), and the run's set-up (mlockall, SCHED_FIFO priority, CPU
 * affinity of the calling thread) with what it refused, restored after the run.
 */
#ifndef HIL_NATIVE_LOOP_RT_H
#define HIL_NATIVE_LOOP_RT_H

#include <stdint.h>

#include "loop.h"

/* stack of the loop thread touched after the memory lock [bytes] */
#define NL_STACK_PREFAULT (256 * 1024)

/* What the set-up changed, for nl_rt_restore. */
typedef struct {
    int32_t locked;            /* mlockall done */
    int32_t sched_set;         /* policy changed */
    int32_t old_policy;
    int32_t old_priority;
    int32_t affinity_set;
    uint8_t old_mask[128];     /* cpu_set_t of the thread before (1024 CPUs) */
} nl_rt_saved_t;

/* CLOCK_MONOTONIC [ns]. */
int64_t nl_now_ns(void);

/* Sleep until `spin_ns` before `deadline_ns` if it is further away, then busy-wait for it; returns the time
 * the wait ended [ns]. */
int64_t nl_wait_until(int64_t deadline_ns, int64_t spin_ns);

/* Apply the timing group's memory lock, priority and CPU to the calling thread; errno of each refused call into r. */
void nl_rt_setup(const nl_timing_cfg_t *cfg, nl_result_t *r, nl_rt_saved_t *saved);

/* What a bare busy loop sees on this machine: for duration_ns it reads CLOCK_MONOTONIC back to back (on `cpu`
 * if >= 0, at SCHED_FIFO `rt_priority` if > 0, memory locked) and counts the gaps between two reads longer than
 * gap_ns — time the thread did not run (interrupts, other tasks, a hypervisor running another guest). It is
 * the floor under any loop's lateness on this machine. Returns 0, or the errno of a refused set-up call. */
typedef struct {
    int64_t reads;             /* clock reads */
    int64_t gaps;              /* gaps longer than gap_ns */
    int64_t gaps_10us;         /* gaps longer than 10 µs */
    int64_t max_gap_ns;
    int64_t lost_ns;           /* total time in gaps longer than gap_ns */
    int64_t hist[NL_LATE_BINS]; /* gaps per 1 us bin (the last open-ended), as the loop's lateness histogram */
} nl_gap_probe_t;
int32_t nl_gap_probe(int64_t duration_ns, int64_t gap_ns, int32_t cpu, int32_t rt_priority, nl_gap_probe_t *out);

/* Count one period start `late_ns` late into r's lateness histogram (1 us bins, NL_LATE_BINS, the last open-ended;
 * negative lateness counts in bin 0) and its maximum: a few instructions per period, no Python per period. */
void nl_late_count(nl_result_t *r, int64_t late_ns);

/* Undo what nl_rt_setup changed. */
void nl_rt_restore(const nl_rt_saved_t *saved);

#endif
