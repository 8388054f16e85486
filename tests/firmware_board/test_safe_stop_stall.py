"""The safe stop's confirmation counts the target's own time (src/pmsm_hil/hil/runner/safe_stop.py with
src/pmsm_hil/hil/runner/target_time.py), as the lockstep wait for a Command does: a target process the host stops
(SIGSTOP) or starves is a host stall, waited for up to the host-stall limit, never "safe stop not confirmed"; one
that had its time and did not confirm still is. End to end: a SIL target stopped for 1.5 s when the disabling
Setpoint is sent confirms once continued, the run completes (exit 0) and counts the host stall."""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from collections import deque
from collections.abc import Iterator
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.runner import loop as loop_module
from pmsm_hil.hil.runner.contract import EndCode
from pmsm_hil.hil.runner.loop_outcome import LoopOutcome
from pmsm_hil.hil.runner.recorder import frame_records, period_records
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.safe_stop import SAFE_STOP_TIMEOUT_S, disable_and_confirm, settle_ending
from pmsm_hil.hil.runner.target_client import HostStallError
from pmsm_hil.hil.runner.target_time import TargetTime
from pmsm_hil.protocol.ids import NodeState
from tests.firmware_board._runs import rated


class _Client:
    """A TargetClient stand-in whose target confirms `answer_after_s` of wall time after the Setpoint (None:
    never)."""

    def __init__(self, answer_after_s: float | None) -> None:
        self.heartbeats: deque[Any] = deque()
        self.frames_in = 0
        self._answer_after_s = answer_after_s
        self._sent = 0.0

    def serve(self) -> None:
        if self._sent and self._answer_after_s is not None and \
                time.monotonic() - self._sent >= self._answer_after_s and not self.frames_in:
            self.frames_in = 1
            self.heartbeats.append(SimpleNamespace(state=int(NodeState.IDLE)))

    def set_setpoint(self, **kw: Any) -> None:
        assert kw["enable"] is False
        self._sent = time.monotonic()


@pytest.fixture
def idle_process() -> Iterator[subprocess.Popen[bytes]]:
    """A process that sleeps (waits, as an idle target waits for a frame)."""
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    time.sleep(0.2)
    yield proc
    with contextlib.suppress(ProcessLookupError):
        os.kill(proc.pid, signal.SIGCONT)
    proc.kill()
    proc.wait()


def _continue(pid: int) -> None:
    with contextlib.suppress(ProcessLookupError):  # the test ended and its process is gone
        os.kill(pid, signal.SIGCONT)


def _stop_for(pid: int, seconds: float) -> None:
    os.kill(pid, signal.SIGSTOP)
    timer = threading.Timer(seconds, _continue, (pid,))
    timer.daemon = True
    timer.start()


def _completed() -> LoopOutcome:
    return LoopOutcome(period_records(), frame_records(), np.zeros(0), 0)


def test_a_stopped_target_that_confirms_once_continued_is_confirmed(
        idle_process: subprocess.Popen[bytes]) -> None:
    """Its confirmation comes 1 s (wall) after the Setpoint while the host kept it stopped 1.2 s: confirmed, the
    wait counted as a host stall; by wall time alone the same answer is "not confirmed"."""
    _stop_for(idle_process.pid, 1.2)
    stop = disable_and_confirm(_Client(1.0), 1,  # type: ignore[arg-type]
                               clock=TargetTime(idle_process.pid, SAFE_STOP_TIMEOUT_S))
    assert stop.confirmed and stop.wait_ms >= 1000 and not stop.host_stalled
    assert stop.host_stall_s >= 0.5
    out = _completed()
    assert settle_ending(out, stop) is False
    assert out.end_code == int(EndCode.COMPLETED) and out.host_stalls == 1 and out.host_stall_s >= 0.5
    by_wall = disable_and_confirm(_Client(1.0), 1)  # type: ignore[arg-type]
    assert not by_wall.confirmed and by_wall.observed.startswith("no HeartbeatTarget in state idle within 500 ms")


def test_a_target_kept_stopped_past_the_limit_is_the_hosts_error(idle_process: subprocess.Popen[bytes]) -> None:
    _stop_for(idle_process.pid, 5.0)
    stop = disable_and_confirm(_Client(None), 1,  # type: ignore[arg-type]
                               clock=TargetTime(idle_process.pid, SAFE_STOP_TIMEOUT_S), stall_limit_s=1.0)
    assert not stop.confirmed and stop.host_stalled and stop.wait_ms >= 1000
    assert stop.observed.startswith(f"host stall: the target's process (pid {idle_process.pid}) was kept stopped")
    assert "--host-stall-limit 1 s" in stop.observed
    out = _completed()
    assert settle_ending(out, stop) is True
    assert out.end_code == int(EndCode.INTERNAL_ERROR) and isinstance(out.error, HostStallError)
    assert out.end_reason.startswith("host stall: ") and out.host_stalls == 1


def test_an_idle_target_that_does_not_confirm_is_not_confirmed(idle_process: subprocess.Popen[bytes]) -> None:
    """It had its time (asleep, waiting for a frame, counts): the same verdict at the same 0.5 s as by wall time."""
    stop = disable_and_confirm(_Client(None), 1,  # type: ignore[arg-type]
                               clock=TargetTime(idle_process.pid, SAFE_STOP_TIMEOUT_S))
    assert not stop.confirmed and not stop.host_stalled
    assert stop.observed == ("no HeartbeatTarget in state idle within 500 ms (of the target process's own time) of "
                             "the disabling Setpoint (no frame at all)")
    out = _completed()
    settle_ending(out, stop)
    assert out.end_code == int(EndCode.SAFETY_STOP)


def test_a_sil_target_stopped_at_the_safe_stop_confirms_once_continued(reference_sil: Path, tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    real = loop_module.disable_and_confirm
    stopped: list[int] = []

    def stop_then_confirm(client: Any, controller_id: int, **kw: Any) -> Any:
        clock = kw.get("clock")
        assert isinstance(clock, TargetTime)
        _stop_for(clock.pid, 1.5)
        stopped.append(clock.pid)
        return real(client, controller_id, **kw)

    monkeypatch.setattr(loop_module, "disable_and_confirm", stop_then_confirm)
    m = run_closed_loop(rated(f"sil:{reference_sil}", settle_s=0.01, duration_s=0.02, out_dir=tmp_path)).metrics
    assert stopped
    assert m["end_code"] == 0, m["end_reason"]
    assert m["safe_stop_confirmed"] is True and m["safe_stop_wait_ms"] >= 1000
    assert m["host_stalls"] >= 1 and m["host_stall_s"] >= 0.5
    assert any(w.startswith("host stall:") for w in m["warnings"])


@pytest.fixture
def spinning_process() -> Iterator[subprocess.Popen[bytes]]:
    """A process that computes without end (as a firmware in an endless loop)."""
    proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    time.sleep(0.2)
    yield proc
    _continue(proc.pid)
    proc.kill()
    proc.wait()


def test_the_hang_watch_counts_cpu_time_not_the_time_the_host_kept_the_process_stopped(
        spinning_process: subprocess.Popen[bytes], idle_process: subprocess.Popen[bytes],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """After a missing Command the SIL process is watched: a spinning one is hung once it used HANG_CONFIRM_S of
    CPU time, which a stop does not count (it only makes the watch longer); an idle one is not hung."""
    from pmsm_hil.hil.runner import sil_watch

    monkeypatch.setattr(sil_watch, "HANG_CONFIRM_CEILING_S", 20.0)
    _stop_for(spinning_process.pid, 1.0)
    t0 = time.monotonic()
    rc, hung = sil_watch._watch(spinning_process, sil_watch.HANG_CONFIRM_S, unknown_busy=True, own_time=True)
    assert rc is None and hung
    assert time.monotonic() - t0 >= 1.0 + sil_watch.HANG_CONFIRM_S * 0.5  # stopped 1 s, then its CPU time
    assert sil_watch._watch(idle_process, sil_watch.HANG_CONFIRM_S, unknown_busy=True, own_time=True) == (None, False)
