"""A target's lockstep time is its own progress (src/pmsm_hil/hil/runner/c/loop_stall.h): an emulated MCU's
(`nl_guest_available`) the instructions it executed at the virtual time of one, plus the time QEMU slept with nothing
to do; a target process's (`nl_proc_available`, SIL and spawned targets) the CPU time it got, plus the time it slept
waiting for a frame; a starved or stopped target adds nothing. Checked in C (compiled here with loop_stall.c), and
end to end: the instruction-count plugin's running count is mapped by the host and grows only while the guest
executes."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

import pytest

from pmsm_hil.sim_target.qemu import QemuTarget
from tests.host_c import STRICT, compile_c

NATIVE = Path(__file__).resolve().parents[2] / "src" / "pmsm_hil" / "hil" / "runner" / "c"

_CHECK = r"""
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <unistd.h>
#include "loop_stall.h"

static int failures;
static void expect(const char *what, long long got, long long want)
{
    if (got != want) {
        printf("%s: got %lld, want %lld\n", what, got, want);
        failures++;
    }
}

/* A target process (SIL, a spawned target) by the same evidence: its CPU time is its progress. */
static void check_process(void)
{
    const long long ms = 1000000;
    nl_proc_sample_t a = {100000000, 5000000, 0, 0, 0};
    nl_proc_sample_t b = {101000000, 5500000, 0, 0, 0};
    nl_own_time_t own;
    /* asleep at both readings (waiting for a frame): its 1 ms of CPU and the 18.5 ms it slept */
    expect("idle process", nl_proc_available(&a, &b, 20 * ms), 19500000);
    /* runnable at the reading after 2 ms of CPU in 20 ms, its run-queue wait still going on (schedstat counts it
     * only once the thread gets a CPU): the 2 ms it ran, not the 20 ms less the waits counted so far */
    b.exec_ns = a.exec_ns + 2 * ms;
    b.delay_ns = a.delay_ns;
    b.runnable = 1;
    expect("runnable, waiting", nl_proc_available(&a, &b, 20 * ms), 2 * ms);
    /* starved: no CPU at all */
    b.exec_ns = a.exec_ns;
    expect("starved", nl_proc_available(&a, &b, 20 * ms), 0);
    /* spinning: the CPU it got */
    b.exec_ns = a.exec_ns + 20 * ms;
    expect("spinning", nl_proc_available(&a, &b, 20 * ms), 20 * ms);
    /* stopped (SIGSTOP) */
    b.runnable = 0;
    b.stopped = 1;
    b.exec_ns = a.exec_ns;
    expect("stopped", nl_proc_available(&a, &b, 20 * ms), 0);
    /* a wait of this process itself: the first slice counts in full, the rest by the rule */
    nl_own_time_start(&own, (int32_t)getpid(), NULL, 0, 20 * ms, 0);
    expect("started", own.had_ns, 0);
    expect("first slice", nl_own_time_step(&own, 20 * ms), 0);
    expect("first slice counts", own.had_ns, 20 * ms);
    expect("watching", own.watching, 1);
    /* a first slice that lasted 300 ms (the host itself off the CPU): no more than its planned 20 ms */
    nl_own_time_start(&own, (int32_t)getpid(), NULL, 0, 20 * ms, 0);
    expect("late first slice", (nl_own_time_step(&own, 300 * ms), own.had_ns), 20 * ms);
    expect("no process", (nl_own_time_start(&own, 0, NULL, 0, 20 * ms, 0), nl_own_time_step(&own, 20 * ms)), -1);
    expect("nothing counted", own.had_ns, 0);
}

int main(void)
{
    /* QEMU asleep at both readings: 20 ms of wall, 1 ms of CPU, 0.5 ms waiting for one: slept 18.5 ms */
    nl_proc_sample_t a = {100000000, 5000000, 0, 0, 0};
    nl_proc_sample_t b = {101000000, 5500000, 0, 0, 0};
    const long long ms = 1000000;
    expect("idle guest", nl_guest_available(&a, &b, 0, 64, 20 * ms), 18500000);
    /* ... with 1000 instructions of its own on top */
    expect("idle and busy", nl_guest_available(&a, &b, 1000, 64, 20 * ms), 18500000 + 64000);
    /* runnable at the end (a vCPU thread kicked, waiting for a CPU): only its instructions count */
    b.runnable = 1;
    expect("starved", nl_guest_available(&a, &b, 0, 64, 20 * ms), 0);
    expect("starved, some progress", nl_guest_available(&a, &b, 10, 64, 20 * ms), 640);
    /* runnable at the start: the wait then may not be counted yet */
    b.runnable = 0;
    a.runnable = 1;
    expect("runnable at the start", nl_guest_available(&a, &b, 0, 64, 20 * ms), 0);
    /* a thread in disk wait (the plugin's write under writeback pressure): not idle by choice */
    b.disk_wait = 1;
    expect("disk wait", nl_guest_available(&a, &b, 0, 64, 20 * ms), 0);
    b.disk_wait = 0;
    /* stopped (SIGSTOP) at either reading */
    a.runnable = 0;
    b.stopped = 1;
    expect("stopped", nl_guest_available(&a, &b, 0, 64, 20 * ms), 0);
    b.stopped = 0;
    a.stopped = 1;
    expect("continued", nl_guest_available(&a, &b, 0, 64, 20 * ms), 0);
    /* the process's threads ran and waited more than the wall time between (several threads): no sleep */
    a.stopped = 0;
    b.exec_ns = a.exec_ns + 15 * ms;
    b.delay_ns = a.delay_ns + 10 * ms;
    expect("busy threads", nl_guest_available(&a, &b, 0, 64, 20 * ms), 0);
    /* a spinning guest: its instructions, however little wall time */
    expect("spinning", nl_guest_available(&a, &b, 1000000, 64, 20 * ms), 64000000);
    expect("no wall time", nl_guest_available(&a, &b, 0, 64, 0), 0);
    check_process();
    return failures;
}
"""


def test_the_guest_time_counts_instructions_and_idle_sleep_only(tmp_path: Path) -> None:
    src = tmp_path / "check.c"
    src.write_text(_CHECK)
    exe = compile_c(tmp_path / "check", [*STRICT, "-I", str(NATIVE), str(src), str(NATIVE / "loop_stall.c")])
    proc = subprocess.run([str(exe)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout


@pytest.mark.timing
def test_the_hosts_map_of_the_count_grows_while_the_guest_runs(reference_elf: Path) -> None:
    """The guest boots and then waits in WFI for a frame: its count grows, then stays put (timing: a QEMU starved
    for 50 ms in mid-boot looks settled)."""
    qemu = QemuTarget(reference_elf)
    try:
        assert qemu.progress_address() != 0
        deadline = time.monotonic() + 30.0
        while (qemu.executed_instructions() or 0) == 0 and time.monotonic() < deadline:
            time.sleep(0.01)
        booted = qemu.executed_instructions()
        assert booted is not None and booted > 0
        settled = booted
        for _ in range(300):  # until the boot code is done: two readings 50 ms apart that agree
            time.sleep(0.05)
            now = qemu.executed_instructions()
            assert now is not None
            if now == settled:
                break
            settled = now
        time.sleep(0.2)
        assert qemu.executed_instructions() == settled, "the count moved while the guest waited for a frame"
    finally:
        qemu.close()
    assert qemu.executed_instructions() is None and qemu.progress_address() == 0
