"""Lockstep never blames the firmware for the host: a target process the host stops (SIGSTOP) for 3 s
in mid-run is a host stall — the run waits on and completes with the same records as an undisturbed run,
`host_stalls` >= 1 — for a SIL target process, QEMU and a spawned native target, in the C loop and in the test
suite's Python loop (`--loop python`, its `LockstepWait`) alike; a stall longer than `--host-stall-limit` ends as
the host's error (exit 1), not the firmware's (exit 4); a firmware that had its time and did not answer keeps its
verdict at the same period (the endless loop at step 500: "target hung", tests/firmware_board/test_sil_isolation.py
and test_qemu_endings.py)."""

from __future__ import annotations

import contextlib
import os
import resource
import signal
import subprocess
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.runlog.reader import read_periods
from pmsm_hil.hil.runner.run import RunResult, run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.target_client import HostStallError
from tests.firmware_board._at_period import at_period
from tests.firmware_board._runs import rated

#: record fields that are the host's own wall-clock measurements (a SIL step's execution time on the host)
_HOST_TIMED = ("exec_time_ns", "exec_split_ns")
STOP_S = 3.0
#: run lengths [s] after the settle. The C loop's runs stop the target from a watcher of the loop's own period
#: counter (`at_period`) at STOP_PERIOD, long before the run's end: the stall comes mid-run whatever the C loop's
#: ring and block sizes, and the run needs only periods enough to outlast the watcher's reaction (a SIL or spawned
#: target runs ~5000 periods/s here, QEMU ~1000 and ~1.5 CPU-ms each: its periods are the test's largest part).
#: The Python loop hands each block of ClosedLoop.BLOCK (1000) periods to `live` from the loop itself: the first
#: block and 100 periods after it are enough. The stop must come with a block before the last one (`stopped_at`):
#: a stop that came only with the run's last block would stall the safe stop, not the periods
DURATION_S = {"sil": 0.1, "spawn": 0.1, "qemu": 0.05, "python": 0.09}
#: the C loop's period at which `at_period` stops the target (of QEMU's 700 periods, of the others' 1200)
STOP_PERIOD = 100
#: the most CPU the host may use while the target is stopped, as a share of the stop: a host that waits asleep
#: uses 0.02-0.07 (the Python loop's looks between its sleeps included), one that spins 0.3-0.5 on this 2-core
#: machine at load 5 (less the busier the machine: the bound catches a spin up to load ~8)
HOST_CPU_SHARE = 0.2


def _duration_s(kind: str, loop: str) -> float:
    return DURATION_S["python" if loop == "python" else kind]


def _children_with(marker: bytes) -> list[int]:
    """The ids of this process's children whose command line holds `marker`."""
    me = os.getpid()
    return [int(pid) for pid in Path(f"/proc/{me}/task/{me}/children").read_text().split()
            if marker in Path(f"/proc/{pid}/cmdline").read_bytes()]


def _cpu_s() -> float:
    """CPU time of this process so far (every thread: the loop's, the drain's, the logger's) [s]."""
    use = resource.getrusage(resource.RUSAGE_SELF)
    return use.ru_utime + use.ru_stime


def _stop_child(marker: bytes, stop_s: float, stopped: list[int], period: int, stopped_at: list[int] | None,
                host_cpu_s: list[float] | None) -> None:
    """Stop this process's child whose command line holds `marker` and continue it `stop_s` later; `period` (the
    last one run) goes to `stopped_at`, the CPU time this process (the host) used while the target was stopped to
    `host_cpu_s`."""
    for pid in _children_with(marker)[:1]:
        cpu0 = _cpu_s()
        os.kill(pid, signal.SIGSTOP)
        stopped.append(pid)
        if stopped_at is not None:
            stopped_at.append(period)
        timer = threading.Timer(stop_s, _continue, (pid, cpu0, host_cpu_s))
        timer.daemon = True
        timer.start()


def _stopper(marker: bytes, stop_s: float, stopped: list[int], stopped_at: list[int] | None = None,
             host_cpu_s: list[float] | None = None) -> Callable[[np.ndarray], None]:
    """A `live` hook that stops the target (`_stop_child`) after the first block of periods (the Python loop hands
    it over from the loop itself)."""

    def live(block: np.ndarray) -> None:
        if not stopped:
            _stop_child(marker, stop_s, stopped, int(block["seq"][-1]), stopped_at, host_cpu_s)

    return live


def _run_stopped(cfg: RunConfig, marker: bytes, stopped: list[int], stopped_at: list[int] | None = None,
                 host_cpu_s: list[float] | None = None) -> RunResult:
    """`cfg`'s run with its target stopped for STOP_S in mid-run: from the first block (`live`) in the Python loop,
    at STOP_PERIOD (`counter`) in the C loop."""
    if cfg.loop == "python":
        return run_closed_loop(cfg, live=_stopper(marker, STOP_S, stopped, stopped_at, host_cpu_s))
    def stop(done: int) -> None:
        _stop_child(marker, STOP_S, stopped, done - 1, stopped_at, host_cpu_s)

    with at_period(STOP_PERIOD, stop) as counter:
        return run_closed_loop(cfg, counter=counter)


def _continue(pid: int, cpu0: float, host_cpu_s: list[float] | None) -> None:
    if host_cpu_s is not None:
        host_cpu_s.append(_cpu_s() - cpu0)
    with contextlib.suppress(ProcessLookupError):  # a run that ended meanwhile stopped it
        os.kill(pid, signal.SIGCONT)


def _same_records(a: np.ndarray, b: np.ndarray) -> None:
    assert len(a) == len(b)
    for name in a.dtype.names or ():
        if name not in _HOST_TIMED:
            np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def _targets(kind: str, reference_sil: Path, reference_elf: Path) -> tuple[dict[str, Any], bytes]:
    if kind == "sil":
        return {"target": f"sil:{reference_sil}"}, b"--sil"
    if kind == "qemu":
        return {"target": f"qemu:{reference_elf}"}, b"qemu-system-arm"
    return {"target": "spawn", "link": "udp"}, b"--parent-pid"  # `hil target`, native or Python


@pytest.mark.parametrize(("kind", "loop"), [("sil", "native"), ("qemu", "native"), ("spawn", "native"),
                                            ("spawn", "python"), ("sil", "python")])
def test_a_target_stopped_for_3_s_is_a_host_stall_and_the_run_completes(kind: str, loop: str,
                                                                        request: pytest.FixtureRequest,
                                                                        tmp_path: Path) -> None:
    sil = request.getfixturevalue("reference_sil") if kind == "sil" else Path()
    elf = request.getfixturevalue("reference_elf") if kind == "qemu" else Path()
    where, marker = _targets(kind, sil, elf)
    target, link = where["target"], where.get("link", "virtual")
    runs = {}
    stopped_at: list[int] = []
    host_cpu_s: list[float] = []
    for name in ("calm", "stopped"):
        stopped: list[int] = []
        out = tmp_path / name
        cfg = rated(target, link=link, settle_s=0.02, out_dir=out, loop=loop, duration_s=_duration_s(kind, loop))
        res = (_run_stopped(cfg, marker, stopped, stopped_at, host_cpu_s) if name == "stopped"
               else run_closed_loop(cfg))
        assert res.metrics["loop"] == loop
        m = res.metrics
        assert m["end_code"] == 0, m["end_reason"]
        runs[name] = (m, read_periods(out / "run.mcap"), stopped)
    stalled = runs["stopped"][0]
    assert runs["stopped"][2], "the target's process was not found"
    assert stopped_at[0] < stalled["end_period"], (stopped_at, stalled["end_period"])  # mid-run, not at the end
    assert stalled["host_stalls"] >= 1 and stalled["host_stall_s"] >= 1.0
    assert any(w.startswith("host stall:") for w in stalled["warnings"])
    # the host waits for the stopped target asleep, not spinning (a spin takes the CPU a starved target needs)
    assert host_cpu_s[0] < HOST_CPU_SHARE * STOP_S, host_cpu_s
    _same_records(runs["calm"][1], runs["stopped"][1])


@pytest.mark.parametrize("loop", ["native", "python"])
def test_a_stall_past_the_limit_is_the_hosts_error_not_the_firmwares(loop: str, reference_sil: Path,
                                                                     tmp_path: Path) -> None:
    stopped: list[int] = []
    res = _run_stopped(rated(f"sil:{reference_sil}", settle_s=0.02, duration_s=_duration_s("sil", loop),
                             out_dir=tmp_path, host_stall_limit_s=1.0, loop=loop), b"--sil", stopped)
    m = res.metrics
    assert stopped
    assert m["end_code"] == 1, m["end_reason"]
    assert isinstance(res.outcome.error, HostStallError)
    assert m["end_reason"].startswith("host stall: the target's process"), m["end_reason"]
    assert "--host-stall-limit 1 s" in m["end_reason"] and m["dut_violations"] == 0
    assert len(read_periods(tmp_path / "run.mcap")) == m["end_period"] + 1


@pytest.mark.parametrize(("kind", "loop"), [("sil", "native"), ("qemu", "native"), ("sil", "python")])
def test_a_target_that_had_its_time_keeps_its_violation_at_the_same_period(kind: str, loop: str,
                                                                           request: pytest.FixtureRequest) -> None:
    """A Measurement lost on the way (injected): the firmware runs on, idle, and never answers that period; the
    verdict is the same `missing` finding at the same period as with the in-process target (no wall time; QEMU's
    guest by its own progress: its idle time counts)."""
    lib = request.getfixturevalue("reference_sil" if kind == "sil" else "reference_elf")
    faults = "drop.up=0.01,seed=3"
    inproc = run_closed_loop(rated(settle_s=0.01, duration_s=0.05, faults=faults)).metrics
    m = run_closed_loop(rated(f"{kind}:{lib}", settle_s=0.01, duration_s=0.05, faults=faults,
                              step_timeout_s=0.2, lockstep_timeout_s=0.2, loop=loop)).metrics
    assert inproc["end_code"] == m["end_code"] == 4, m["end_reason"]
    clock = "emulated MCU's own time" if kind == "qemu" else "target process's own time"
    assert "missing: no Command" in m["end_reason"] and clock in m["end_reason"], m["end_reason"]
    assert m["end_period"] == inproc["end_period"]



#: busy loops beside QEMU on its CPU: QEMU's threads then wait on a run queue most of each slice (the load under
#: which QEMU's process time, the rule before the guest's progress, gave 4 false exit 4 in 4 runs, docs/runner.md)
BURNERS = 4


def _pin_child(marker: bytes, cpu: int, pinned: list[int]) -> Callable[[np.ndarray], None]:
    """A `live` hook that pins every thread of this process's child whose command line holds `marker` to `cpu`."""

    def live(block: np.ndarray) -> None:
        if pinned:
            return
        for pid in _children_with(marker):
            for tid in os.listdir(f"/proc/{pid}/task"):
                with contextlib.suppress(OSError):
                    os.sched_setaffinity(int(tid), {cpu})
            pinned.append(pid)

    return live


@pytest.mark.timing
@pytest.mark.parametrize("kind", ["qemu", "sil"])
def test_a_target_beside_busy_loops_on_its_cpu_completes(kind: str, request: pytest.FixtureRequest,
                                                         tmp_path: Path) -> None:
    """The target's process pinned to one CPU with BURNERS busy loops: it progresses slowly but has nothing to
    answer for; the run completes (timing: minutes on a loaded machine). QEMU is judged by its guest's progress,
    a SIL target process by the CPU time it got and the time it slept waiting for a frame: never by wall time
    less the run-queue waits counted so far, which misses the wait still going on when the process is read."""
    sil = request.getfixturevalue("reference_sil") if kind == "sil" else Path()
    elf = request.getfixturevalue("reference_elf") if kind == "qemu" else Path()
    where, marker = _targets(kind, sil, elf)
    cpu = max(os.sched_getaffinity(0))
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(BURNERS)]
    pinned: list[int] = []
    try:
        for b in burners:
            os.sched_setaffinity(b.pid, {cpu})
        m = run_closed_loop(rated(where["target"], settle_s=0.02, duration_s=0.2 if kind == "qemu" else 0.3,
                                out_dir=tmp_path),
                            live=_pin_child(marker, cpu, pinned)).metrics
    finally:
        for b in burners:
            b.kill()
            b.wait()
    assert pinned
    assert m["end_code"] == 0, m["end_reason"]
