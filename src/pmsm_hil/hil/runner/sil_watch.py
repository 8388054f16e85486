"""The SIL target in its own process: the run's settings for it and how its ending is told.

`hil run --target sil:PATH` serves the library from a `hil target --native --sil PATH` process over a private
link (the serial framing over a Unix socket pair unless `--link` names a udp or serial link), so the runner
survives whatever the user's code does. A crash (a signal, an exit) or a step longer than `--step-timeout`
leaves the period's Command missing; the loop ends on it as on any silent target (safe stop, every period
logged), and `judge` then names the cause: "target crashed (SIGSEGV at period N)" or "target hung", both
`EndCode.SAFETY_STOP` (exit 3). `InterruptGuard` kills a target process that is still running shortly after
Ctrl-C/SIGTERM, so a hung step cannot hold the run.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import signal
import subprocess
import threading
import time
from types import FrameType
from typing import Any

from pmsm_hil.hil.runner.contract import MISSING, EndCode
from pmsm_hil.hil.runner.loop_outcome import LoopOutcome
from pmsm_hil.hil.runner.run_config import RunConfig

#: link kinds an isolated SIL target can be served over (the native target's C loop) when `--link` names one
SIL_LINK_KINDS = ("udp", "serial")
#: the link of an isolated SIL run given `--link virtual` (the default): the serial framing over a Unix socket
#: pair (the target process inherits one end), so the runner sees the target's death at once (end of file)
SOCKETPAIR_LINK = "serial:socketpair"
#: ... in real time: two free UDP ports on 127.0.0.1
REALTIME_LINK = "udp"
#: wall time [s] a SIL target process gets to end after SIGTERM before SIGKILL (an endless loop ignores
#: SIGTERM; Ctrl-C must end the run within 1 s)
SIL_STOP_WAIT_S = 0.2
#: lockstep: CPU time [s] a SIL target process that left a Command missing (after --step-timeout of its own time)
#: must use in the watch that follows, computing all along (never once waiting for a frame) and not exiting, to be
#: taken as hung: its own time, so a host that stops or starves it meanwhile only makes the watch longer
HANG_CONFIRM_S = 0.3
#: ... the longest wall time [s] that watch lasts (a process the host keeps stopped or starved): then it is taken
#: as hung if it still never waited for a frame, as before the watch counted CPU time
HANG_CONFIRM_CEILING_S = 30.0
#: how often the watch samples the process [s]
HANG_SAMPLE_S = 0.002
#: how often a `BusyWatch` samples it while the host waits for a ConfigAck [s]
HANG_SAMPLE_BUSY_S = 0.02
#: after Ctrl-C/SIGTERM, wall time [s] before a SIL target process still running is killed (a loop waiting
#: for a hung step's Command then ends at once on the closed socket)
SIL_INTERRUPT_KILL_S = 0.25


def isolated_config(cfg: RunConfig) -> RunConfig:
    """The run's settings for an isolated SIL target: its link (a virtual one becomes the socket pair, UDP in
    real time) and the wait for each Command (`--step-timeout`); any other run unchanged."""
    if not cfg.sil_isolated:
        return cfg
    if cfg.link_spec.kind.lower() in SIL_LINK_KINDS:
        link = cfg.link
    else:  # real time: UDP (the socket pair has no bit rate for the link budget; a miss is seen within Ts anyway)
        link = SOCKETPAIR_LINK if cfg.mode == "lockstep" else REALTIME_LINK
    return dataclasses.replace(cfg, link=link, lockstep_timeout_s=cfg.step_timeout_s)


def ending_place(out: LoopOutcome) -> str:
    """Where a target's process ended, for the run's reason: at the period its final silence began, after the
    last period, or while being configured."""
    period = silent_since(out)
    if period is not None:
        return f"at period {period}"
    return f"after period {out.completed_periods - 1}" if out.completed_periods else "while being configured"


def silent_since(out: LoopOutcome) -> int | None:
    """The first period of the last unbroken run of missing Commands up to the end (the period the target fell
    silent in: real-time misses before it do not count), None if none or beyond the kept findings."""
    if out.violation_count > len(out.violations):
        return None
    since, last = None, None
    for v in out.violations:
        if v.rule != MISSING:
            continue
        if last is None or v.period != last + 1:
            since = v.period
        last = v.period
    return since if last is not None and last >= out.completed_periods - 1 else None


def ended_silent(out: LoopOutcome) -> bool:
    """The loop ended because Commands went missing (contract `missing`, or the watchdog)."""
    if out.end_code == EndCode.DUT_VIOLATION:
        return bool(out.violations) and out.violations[-1].rule == MISSING
    return out.end_code == EndCode.SAFETY_STOP and out.end_reason.startswith("watchdog")


def describe_exit(returncode: int) -> str:
    """`SIGSEGV` for a death by signal 11, `exit code 2` for an exit."""
    if returncode < 0:
        try:
            return signal.Signals(-returncode).name
        except ValueError:
            return f"signal {-returncode}"
    return f"exit code {returncode}"


def _state(pid: int) -> str | None:
    """The scheduler state of process `pid` (R running, S sleeping, ...; Linux /proc), None if unknown."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as f:
            return f.read().rsplit(")", 1)[1].split()[0]
    except (OSError, IndexError):
        return None


def cpu_s(pid: int) -> float | None:
    """CPU time [s] process `pid` used so far, all threads (Linux /proc), None if unknown."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii", errors="replace") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return None


class BusyWatch:
    """Whether a target process computes without once waiting for a frame while the host waits for its answer
    (a configuration's ConfigAck): `hung()` is true once it stayed runnable (state R at every sample) and used
    `limit_s` of CPU time meanwhile — its own time, so a host that starves it is never taken for a hang."""

    def __init__(self, pid: int, limit_s: float) -> None:
        self.pid, self.limit_s = pid, limit_s
        self._cpu0: float | None = None
        self._next = 0.0

    def hung(self) -> bool:
        """Sample the process (at most every `HANG_SAMPLE_BUSY_S`); True once it is hung."""
        now = time.monotonic()
        if now < self._next:
            return False
        self._next = now + HANG_SAMPLE_BUSY_S
        if _state(self.pid) != "R":
            self._cpu0 = None
            return False
        cpu = cpu_s(self.pid)
        if cpu is None:
            return False
        if self._cpu0 is None:
            self._cpu0 = cpu
        return cpu - self._cpu0 >= self.limit_s

    @property
    def cpu_used_s(self) -> float:
        """CPU time [s] of the current busy spell (0 when none)."""
        cpu = cpu_s(self.pid) if self._cpu0 is not None else None
        return cpu - self._cpu0 if cpu is not None and self._cpu0 is not None else 0.0


def _watch(proc: subprocess.Popen[bytes], seconds: float, unknown_busy: bool,
           own_time: bool = False) -> tuple[int | None, bool]:
    """Watch a target process that left a Command missing for up to `seconds` (`own_time`: of its CPU time, within
    `HANG_CONFIRM_CEILING_S` of wall time; else wall time): (its exit status if it ended meanwhile — a dying process
    closes its socket a little before it can be reaped —, whether it computed the whole time without once waiting
    for a frame: hung). Without /proc: `unknown_busy`."""
    start = time.monotonic()
    deadline = start + (HANG_CONFIRM_CEILING_S if own_time else seconds)
    cpu0 = cpu_s(proc.pid) if own_time else None
    known = False
    while True:
        rc = proc.poll()
        if rc is not None:
            return rc, False
        state = _state(proc.pid)
        known = known or state is not None
        if state == "S":  # waiting in its link's poll: alive and idle, the frame was lost or ignored
            return None, False
        now = time.monotonic()
        if now >= deadline:
            return None, unknown_busy if not known else True
        if cpu0 is not None and now - start >= HANG_SAMPLE_S:
            cpu = cpu_s(proc.pid)
            if cpu is not None and cpu - cpu0 >= seconds:
                return None, True
        time.sleep(HANG_SAMPLE_S)


def judge_setup(proc: subprocess.Popen[bytes], out: LoopOutcome, hung_in: str | None, initialised: bool,
                step_timeout_s: float) -> bool:
    """Name the SIL target's part in an ending while it was being set up (rewritten in place): hung in
    hil_app_init or hil_app_config (`hung_in`: its `BusyWatch` fired), or crashed in hil_app_init (not yet
    `initialised`). True when it is hung (the caller kills it)."""
    if out.end_code != EndCode.DUT_VIOLATION or out.completed_periods:
        return False
    if hung_in is not None and proc.poll() is None:
        out.end_code = int(EndCode.SAFETY_STOP)
        out.end_reason = (f"target hung in {hung_in}: it computed for --step-timeout {step_timeout_s:g} s of its own "
                          f"CPU time without answering; target process killed, inverter put in the safe state "
                          f"(zero vector)")
        out.safe_state = True
        return True
    if not initialised:
        rc = proc.poll()
        if rc is None:
            with contextlib.suppress(subprocess.TimeoutExpired):
                rc = proc.wait(HANG_CONFIRM_S)
        if rc is not None:
            out.end_code = int(EndCode.SAFETY_STOP)
            out.end_reason = (f"target crashed ({describe_exit(rc)} in hil_app_init); inverter put in the safe "
                              f"state (zero vector)")
            out.safe_state = True
            out.error = None
    return False


def judge(proc: subprocess.Popen[bytes], out: LoopOutcome, step_timeout_s: float, realtime: bool = False) -> bool:
    """Name the SIL target's part in the ending `out` (rewritten in place): its process died (crashed), or it
    left a Command missing and is still computing (hung: lockstep, the wait was --step-timeout already, so
    `HANG_CONFIRM_S` more of its CPU time; real time, a missed deadline, so --step-timeout more of wall time). A
    target that waits idle keeps the ending (a contract violation), as does an interrupted run. True when the
    target is hung (the caller kills it rather than waiting)."""
    if out.end_code == EndCode.INTERRUPTED:
        return False
    rc, hung = proc.poll(), False
    link_failed = out.end_code == EndCode.INTERNAL_ERROR  # e.g. a broken pipe: the target's socket closed
    if rc is None and (ended_silent(out) or link_failed):
        rc, hung = _watch(proc, step_timeout_s if realtime else HANG_CONFIRM_S, unknown_busy=not realtime,
                          own_time=not realtime)
    period, where = silent_since(out), ending_place(out)
    if rc is not None:
        out.end_code = int(EndCode.SAFETY_STOP)
        out.end_reason = (f"target crashed ({describe_exit(rc)} {where}); inverter put in the safe state "
                          f"(zero vector)")
        out.safe_state = True
        out.error = None  # the link's error was the target's death, not the tool's
        return False
    if not hung or not ended_silent(out):
        return False
    clock = "wall time" if realtime else "of its process's own time"
    out.end_code = int(EndCode.SAFETY_STOP)
    out.end_reason = (f"target hung: its step for period {period if period is not None else '?'} did not return "
                      f"within --step-timeout {step_timeout_s:g} s ({clock}); target process killed, inverter "
                      f"put in the safe state (zero vector)")
    return True


class InterruptGuard:
    """While armed: on SIGINT/SIGTERM (then handled as before: KeyboardInterrupt) kill `proc` if it still runs
    `SIL_INTERRUPT_KILL_S` later (an orderly stop closes it sooner). Main thread only; elsewhere a no-op."""

    def __init__(self, proc: subprocess.Popen[bytes]) -> None:
        self._proc = proc
        self._previous: dict[int, Any] = {}
        self._done = threading.Event()
        self._timer: threading.Timer | None = None

    def arm(self) -> None:
        """Wrap the SIGINT and SIGTERM handlers."""
        for signum in (signal.SIGINT, signal.SIGTERM):
            try:
                self._previous[signum] = signal.signal(signum, self._on_signal)
            except ValueError:  # not the main thread
                return

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self.on_stop()
        previous = self._previous.get(signum)
        if callable(previous):
            previous(signum, frame)
        elif previous != signal.SIG_IGN:
            raise KeyboardInterrupt

    def on_stop(self) -> None:
        """A stop was asked (a signal, or the run's deferred stop request): kill the process if it still runs
        `SIL_INTERRUPT_KILL_S` later."""
        if self._timer is None and not self._done.is_set():
            self._timer = threading.Timer(SIL_INTERRUPT_KILL_S, self._kill)
            self._timer.daemon = True
            self._timer.start()

    def release_handlers(self) -> None:
        """Give the signal handlers back (the run's deferred stop request takes over; `on_stop` is then its
        hook); a later kill still happens."""
        for signum, handler in self._previous.items():
            with contextlib.suppress(ValueError):
                if signal.getsignal(signum) == self._on_signal:
                    signal.signal(signum, handler)
        self._previous.clear()

    def _kill(self) -> None:
        if not self._done.is_set() and self._proc.poll() is None:
            self._proc.kill()

    def disarm(self) -> None:
        """Restore the handlers (idempotent); a pending kill is dropped."""
        self._done.set()
        if self._timer is not None:
            self._timer.cancel()
        for signum, handler in self._previous.items():
            with contextlib.suppress(ValueError):
                if signal.getsignal(signum) == self._on_signal:  # not replaced since (the runner restores its own)
                    signal.signal(signum, handler)
        self._previous.clear()
