/*
 * Host stalls: what the target's process did while the host waited for its answer (lockstep over a link to a
 * target process the host can observe: a SIL target process, QEMU, a spawned native target; the safe stop's
 * confirmation). Read from Linux /proc/PID/task/TID/{stat,schedstat} (every thread: QEMU computes in a thread of
 * its own): the CPU time the process got, the time its threads waited for a CPU, whether it is stopped (SIGSTOP, a
 * debugger). The host counts only the target's own time against its timeouts -- the time it computed, and the time
 * it slept with nothing to do -- : a stopped or starved target is the host's doing, not the firmware's
 * (docs/runner.md "Host stalls").
 */
#ifndef HIL_NATIVE_LOOP_STALL_H
#define HIL_NATIVE_LOOP_STALL_H

#include <stdint.h>

/* The wait for a Command is cut into slices this long [ns] once it lasts longer (the process is read between
 * them); a reply within the first slice costs no /proc read. */
#define NL_STALL_SLICE_NS 20000000
/* A runnable thread that got less than this share [1/1000] of a slice's wall time was starved by the host. */
#define NL_STALL_STARVED_PERMILLE 50

/* One reading of a process. */
typedef struct {
    int64_t exec_ns;       /* CPU time of all its threads so far [ns] */
    int64_t delay_ns;      /* time its threads waited on a run queue so far [ns] (counted when they got a CPU) */
    int32_t runnable;      /* a thread is running or waiting for a CPU (state R) */
    int32_t stopped;       /* a thread is stopped (state T or t: SIGSTOP, a debugger) */
    int32_t disk_wait;     /* a thread waits in the kernel uninterruptibly (state D: disk I/O, page faults) */
} nl_proc_sample_t;

/* Read process `pid`: 0, or -1 when it is gone (no such process, a zombie) or /proc cannot say. */
int nl_proc_sample(int32_t pid, nl_proc_sample_t *s);

/* A target process's own time [ns] of the wall time `wall_ns` between readings `a` and `b`: the CPU time its
 * threads got in between, plus, when the whole process slept at both readings (no thread runnable, stopped or in
 * disk wait), the time it slept in between (idle by its own choice: waiting for a frame). Time on a run queue --
 * also a wait that is still going on when `b` is read, which schedstat counts only once the thread gets a CPU --,
 * stopped or disk-bound time counts for nothing: nl_guest_available with the process's CPU time as its progress. */
int64_t nl_proc_available(const nl_proc_sample_t *a, const nl_proc_sample_t *b, int64_t wall_ns);

/* A QEMU guest (an emulated MCU running on virtual time) is judged by its own progress, not by its process's CPU
 * time: QEMU accumulates CPU (its main loop, translation, a vCPU thread kicked but starved) without the guest
 * executing, so the process's time over-credits a guest on a loaded host. Of the wall time `wall_ns` between
 * readings `a` and `b` of QEMU's process, the guest's own time [ns]: the instructions it executed (`insns`, counted
 * exactly by the instruction-count plugin) times the virtual time of one (`ns_per_insn`, -icount), plus, when the
 * whole process slept at both readings (no thread runnable, stopped or in disk wait: nothing for QEMU to do, every
 * run-queue wait between them already counted), the time it slept in between -- the guest idle by its own choice
 * (WFI, a blocking doorbell read) with everything the host sent either taken or refused by the guest. Starved,
 * stopped or disk-bound time counts for nothing. */
int64_t nl_guest_available(const nl_proc_sample_t *a, const nl_proc_sample_t *b, int64_t insns, int64_t ns_per_insn,
                           int64_t wall_ns);

/* The target's own time during one wait, read in slices (the C loop's wait for a Command, the safe stop's wait for
 * its confirmation). The first slice counts in full up to `slice_ns` (a guest: its instructions) and costs no /proc
 * read -- a host that itself did not run for longer than a slice knows nothing of the target's chance beyond it --:
 * the process is read from its end on, and every slice after it counts nl_proc_available (a guest:
 * nl_guest_available). */
typedef struct {
    int32_t pid;                 /* the target's process (> 0) */
    const uint64_t *guest_insns; /* an emulated MCU's executed instructions (QEMU's plugin, shared memory), or NULL */
    int64_t ns_per_insn;         /* the virtual time of one of its instructions [ns] */
    int64_t slice_ns;            /* the planned length of a slice [ns]: the most the first one counts */
    int32_t watching;            /* `prev` holds a reading (after the first slice) */
    nl_proc_sample_t prev;
    int64_t insns_prev;
    int64_t t_prev;              /* wall time of the last step [ns] */
    int64_t had_ns;              /* the target's own time since the start [ns] */
} nl_own_time_t;

/* Start counting at wall time `t0_ns` [ns] (nl_now_ns), in slices of `slice_ns` [ns]. */
void nl_own_time_start(nl_own_time_t *o, int32_t pid, const uint64_t *guest_insns, int64_t ns_per_insn,
                       int64_t slice_ns, int64_t t0_ns);

/* Add the slice that ends at wall time `t_ns` to `had_ns`: 0, or -1 when the process cannot be read (gone: the
 * ending names the crash; or not observable) -- `had_ns` then stays as it was. */
int nl_own_time_step(nl_own_time_t *o, int64_t t_ns);

#endif
