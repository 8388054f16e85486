"""The in-process link to the C target core of the native loop (src/pmsm_hil/hil/runner/c/links/link_core.h).

For a run's periods the C loop reaches the core through its C link like any other (`attach`): the frames go to
`hil_core_rx`, the replies come from `hil_core_tx`, the profiled step's stage split and torque reference through
the link's `diag`. Between runs, frames from Python (configuration, the enabling and the disabling Setpoint) go
straight to the core and its replies come back the same way, so `TargetClient` talks to the core as to any
target. The core and the reference firmware keep their state in C globals: one native loop per process at a
time (`NativeCoreLink` holds the lock while open).
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Sequence
from typing import Any

from pmsm_hil.hil.errors import HilError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links.stats import LinkStats

_CORE_LOCK = threading.Lock()


class NativeLoopUnavailableError(HilError):
    """The native loop cannot run this configuration (the reason says why)."""


def native_lib() -> tuple[Any, Any]:
    """(ffi, lib) of the native loop extension; NativeLoopUnavailableError if it was not built."""
    try:
        from pmsm_hil.hil._loop_native import ffi, lib
    except ImportError as exc:
        raise NativeLoopUnavailableError(f"the native loop extension is not built ({exc})") from None
    return ffi, lib


class NativeCoreLink:
    """Link to the C target core; `fd`: the host's frame profile is CAN FD; `silent_after`: the core ignores the
    run's Measurements after this many (a test's fault injection, as `SimTarget(silent_after=...)`; None: never)."""

    def __init__(self, fd: bool, silent_after: int | None = None) -> None:
        self.ffi, self.lib = native_lib()
        if not _CORE_LOCK.acquire(blocking=False):
            raise NativeLoopUnavailableError("another native loop runs in this process (one C target core each)")
        self._locked = True
        self.fd = fd
        self.silent_after = silent_after
        self.stats = LinkStats()
        #: errno of what the last run's real-time set-up was refused: mlockall, SCHED_FIFO, CPU affinity (0: ok)
        self.rt_errnos: tuple[int, int, int] = (0, 0, 0)
        self._out = self.ffi.new("hil_core_frame_t *")
        self._replies: deque[Frame] = deque()
        self._state: Any = None
        self._c_link: Any = None
        self.lib.hil_core_init()

    @property
    def other_process(self) -> bool:
        """The core answers inside the loop's call (its C link is NL_LINK_IN_PROCESS): False."""
        return False

    def attach(self, c: Any, lockstep_timeout_s: float) -> None:
        """Give the loop's nl_config_t `c` the core's C link for a run."""
        self._state = self.ffi.new("nl_core_link_t *")
        self._state.silent_after = -1 if self.silent_after is None else self.silent_after
        self._c_link = self.ffi.new("nl_link_t *")
        self.lib.nl_core_link(self._c_link, self._state)
        c.target_link.link = self._c_link
        c.target_link.lockstep_timeout_ns = int(lockstep_timeout_s * 1e9)

    def detach(self) -> None:
        """After the run: the frames the C link moved into `stats`."""
        if self._state is None:
            return
        self.stats.frames_tx += int(self._state.stats.frames_tx)
        self.stats.frames_rx += int(self._state.stats.frames_rx)
        self._state = None

    def send(self, frames: Sequence[Frame]) -> None:
        """Frames host → core; the core's replies to each are taken at once (its queue holds 8 frames)."""
        rx, tx, out = self.lib.hil_core_rx, self.lib.hil_core_tx, self._out
        for fr in frames:
            self.stats.frames_tx += 1
            rx(fr.arbitration_id, fr.data, len(fr.data), 1 if fr.is_fd else 0)
            while tx(out):
                self._replies.append(Frame(int(out.id), bytes(self.ffi.buffer(out.data, out.len)), bool(out.fd)))

    def poll(self) -> Frame | None:
        """The next reply of the core, or None."""
        if not self._replies:
            return None
        self.stats.frames_rx += 1
        return self._replies.popleft()

    def recv(self, timeout_s: float) -> Frame | None:
        """As `poll`: the core answers inside `send`, so nothing arrives later."""
        return self.poll()

    def close(self) -> None:
        """Release the core for the next native run in this process (idempotent)."""
        if self._locked:
            self._locked = False
            _CORE_LOCK.release()
