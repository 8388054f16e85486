/*
 * Host stalls: what the target's process did while the loop waited for its Command (lockstep over a link to a
 * target process the host can observe: a SIL target process, QEMU, a spawned native target). Read from Linux
 * /proc/PID/task/TID/{stat,schedstat} (every thread: QEMU computes in a thread of its own): the CPU time the
 * process got, the time its threads waited for a CPU, whether it is stopped (SIGSTOP, a debugger). The loop
 * counts only the time the target could run against the lockstep timeout: a stopped or starved target is the
 * host's doing, not the firmware's (docs/runner.md "Host stalls").
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

/* Of the wall time `wall_ns` between readings `a` and `b`, how long the target could run [ns]: none while
 * stopped, its CPU time while runnable but starved, else the wall time less what it waited for a CPU. */
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

#endif
