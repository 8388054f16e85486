"""The logger's view of its runner after a SIGTERM: has the runner stopped feeding it, or is it only not scheduled?

A SIGTERM sent to the whole process group reaches the runner and its logger together; the runner then drains its
loop into the logger and closes it. On a busy machine the runner can wait seconds for a CPU before its last blocks
arrive: a logger that ended after one idle second of wall time dropped them (27 000 of 32 791 periods in a file,
tests/runner/test_interrupt_log.py at load 12–19). So the idle time after SIGTERM counts only while the runner
sleeps (no thread running, waiting for a CPU, stopped or in an uninterruptible wait: Linux /proc); elsewhere, or
when the runner cannot be read, wall time counts as before. `SIGTERM_CEILING_S` without a notice ends it anyway."""

from __future__ import annotations

import os
import time
from typing import Final

SIGTERM_IDLE_S: Final = 1.0  # after SIGTERM: end once the runner slept this long without a notice [s]
SIGTERM_CEILING_S: Final = 30.0  # after SIGTERM: end after this long without a notice, whatever the runner does [s]

_runner_pid: int | None = None


def set_runner(pid: int) -> None:
    """The runner's process id (the spawned logger's parent; the forked one's is the fork server)."""
    global _runner_pid
    _runner_pid = pid


def runner_pid() -> int | None:
    """The runner's process id, None when not set (the worker run by a test directly)."""
    return _runner_pid


def _busy(pid: int) -> bool | None:
    """Whether a thread of process `pid` runs or waits to (R), is stopped (T, t) or in a disk wait (D); None when
    /proc cannot tell (no /proc, or the process gone)."""
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return None
    states = []
    for tid in tids:
        try:
            with open(f"/proc/{pid}/task/{tid}/stat", encoding="ascii", errors="replace") as f:
                states.append(f.read().rsplit(")", 1)[1].split()[0])
        except (OSError, IndexError):
            continue  # a thread that just ended
    if not states:
        return None
    return any(state in ("R", "T", "t", "D") for state in states)


class RunnerIdle:
    """Idle time since the last notice (or the SIGTERM), counted while the runner `pid` sleeps (see module)."""

    def __init__(self, pid: int | None) -> None:
        self.pid = pid
        self.reset()

    def reset(self) -> None:
        """A notice came (or the SIGTERM): idle from now."""
        self._since = self._last = time.monotonic()
        self._last_busy: bool | None = None
        self._idle_s = 0.0

    def over(self) -> bool:
        """Sample the runner; True once it slept `SIGTERM_IDLE_S` (or `SIGTERM_CEILING_S` passed) without a notice."""
        now = time.monotonic()
        busy = _busy(self.pid) if self.pid is not None else None
        interval = now - self._last
        if busy is None or (not busy and self._last_busy is False):  # unknown (wall time), or asleep at both ends
            self._idle_s += interval
        self._last, self._last_busy = now, busy
        return self._idle_s >= SIGTERM_IDLE_S or now - self._since >= SIGTERM_CEILING_S
