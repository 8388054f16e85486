"""A wait in Python for the target's answer, judged as the C loop judges its lockstep wait for a Command
(`await_lockstep`, src/pmsm_hil/hil/runner/c/loop.c): against the target's own time when the host observes its
process (`TargetTime`: a SIL target process, QEMU, a spawned target), else wall time. A target the host kept
stopped or off the CPUs is waited for -- a host stall, counted -- up to the host-stall limit of wall time; a target
that had its time and did not answer is `missing`. The test suite's Python loop and the conformance probe wait so
(docs/runner.md "Host stalls").
"""

from __future__ import annotations

import time
from collections.abc import Callable
from enum import Enum
from typing import TypeVar

from pmsm_hil.hil.runner.target_client import HostStallError
from pmsm_hil.hil.runner.target_time import TargetTime

_T = TypeVar("_T")

#: a wait looks for the answer without pause this long [ns] (a reply on an idle machine comes well inside it),
#: then sleeps between looks, IDLE_FIRST_S at first and twice as long each time up to IDLE_MAX_S [s]: a host that
#: spins while it waits takes the CPU from a starved or stopped target it waits for (the judgement reads the
#: target's own time by the clock, not per look)
SPIN_NS = 500_000
IDLE_FIRST_S = 50e-6
IDLE_MAX_S = 1e-3


class WaitEnd(Enum):
    """How one wait ended."""

    ANSWERED = "answered"
    #: the target had its time (its own, or wall time when it is not observed) and did not answer
    MISSING = "missing"
    #: the host kept the target from running for the whole host-stall limit (the host's fault)
    HOST_STALL = "host stall"
    #: a stop request (Ctrl-C, SIGTERM) ended a wait that the host's stall had prolonged
    INTERRUPTED = "interrupted"


class LockstepWait:
    """Waits of `timeout_s` [s] for the target's answer: of its own time when `clock` observes its process, else
    of wall time; a host stall goes on up to `stall_limit_s` [s] of wall time. Counts the waits that went past the
    timeout because the host kept the target from running (`host_stalls`) and that time (`host_stall_s`)."""

    def __init__(self, clock: TargetTime | None, timeout_s: float, stall_limit_s: float) -> None:
        self.clock = clock
        self.timeout_s = timeout_s
        self.stall_limit_s = stall_limit_s
        self.host_stalls = 0
        self.host_stall_s = 0.0
        #: the wall time [s] of the last wait
        self.wait_s = 0.0
        self._t0 = 0

    def begin(self) -> None:
        """Start a wait now."""
        self._t0 = time.perf_counter_ns()
        if self.clock is not None:
            self.clock.start()

    def judge(self, stop: Callable[[], bool] | None = None) -> WaitEnd | None:
        """After a look that found no answer: how the wait ends now (`MISSING`: look once more, an answer may have
        come while this thread was off the CPU), or None to go on. `stop` is asked between slices."""
        clock = self.clock
        wall_ns = time.perf_counter_ns() - self._t0
        if clock is None:
            return WaitEnd.MISSING if wall_ns >= self.timeout_s * 1e9 else None
        if not clock.observable:  # gone: the ending names the crash (the C loop's wait ends at once too)
            return WaitEnd.MISSING
        clock.step()
        if not clock.observable or clock.had_s >= self.timeout_s:
            return WaitEnd.MISSING
        if stop is not None and stop():
            return WaitEnd.INTERRUPTED
        if wall_ns >= max(self.stall_limit_s, self.timeout_s) * 1e9:
            return WaitEnd.HOST_STALL
        return None

    def finish(self) -> None:
        """End the wait: its wall time in `wait_s`; the host's part of it counted when the timeout alone would
        have ended it and the target was kept from running for a slice or more."""
        wall_s = (time.perf_counter_ns() - self._t0) / 1e9
        self.wait_s = wall_s
        clock = self.clock
        if clock is None or not clock.watching or wall_s <= self.timeout_s:
            return
        lost = wall_s - min(clock.had_s, wall_s)
        if lost >= clock.slice_s:
            self.host_stalls += 1
            self.host_stall_s += lost

    def wait(self, look: Callable[[], _T | None],
             stop: Callable[[], bool] | None = None) -> tuple[_T | None, WaitEnd]:
        """What `look` found (None: nothing) within the wait, and how the wait ended."""
        self.begin()
        got = look()
        spin_end = self._t0 + SPIN_NS
        idle_s = 0.0
        while got is None:
            end = self.judge(stop)
            if end is None:
                if idle_s or time.perf_counter_ns() >= spin_end:
                    idle_s = min(IDLE_MAX_S, 2 * idle_s or IDLE_FIRST_S)
                    time.sleep(idle_s)
                got = look()
                continue
            if end is WaitEnd.MISSING:  # one more look: the answer may have come while this thread was off the CPU
                got = look()
            self.finish()
            return got, WaitEnd.ANSWERED if got is not None else end
        self.finish()
        return got, WaitEnd.ANSWERED

    @property
    def clock_words(self) -> str:
        """What the timeout is counted in, for a reason: `(...)`."""
        clock = self.clock
        return lockstep_clock_words(clock.pid if clock is not None else 0, clock is not None and clock.guest)


def lockstep_clock_words(pid: int, guest: bool) -> str:
    """What a lockstep timeout is counted in for a target in process `pid` (0: none observed), `guest`: an emulated
    MCU judged by its own progress."""
    if guest:
        return "of the emulated MCU's own time: its instructions and idle time"
    return "of the target process's own time" if pid > 0 else "wall time"


def host_stall_error(pid: int, wait_s: float, what: str, limit_s: float) -> HostStallError:
    """The host's error ending a wait of `wait_s` [s] for `what` ("the Command of period 12") that the host-stall
    limit `limit_s` [s] cut short."""
    return HostStallError(f"host stall: the target's process (pid {pid}) was kept stopped or off the CPUs while the "
                          f"run waited {wait_s:.1f} s for {what} (--host-stall-limit {limit_s:g} s); the host's "
                          "fault, not the firmware's")


__all__ = ["LockstepWait", "WaitEnd", "host_stall_error", "lockstep_clock_words"]
