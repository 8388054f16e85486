"""The in-process link to the C target core of the native loop (src/pmsm_hil/hil/runner/c/loop.c).

Between runs of the C loop, frames from Python (configuration, the enabling and the disabling Setpoint) go
straight to the core (`hil_core_rx`) and its replies come back from `hil_core_tx`, so `TargetClient` talks to
the core as to any target. The core and the reference firmware keep their state in C globals: one native
loop per process at a time (`NativeCoreLink` holds the lock while open).
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
    """Link to the C target core; `fd`: the host's frame profile is CAN FD."""

    def __init__(self, fd: bool) -> None:
        self.ffi, self.lib = native_lib()
        if not _CORE_LOCK.acquire(blocking=False):
            raise NativeLoopUnavailableError("another native loop runs in this process (one C target core each)")
        self._locked = True
        self.fd = fd
        self.stats = LinkStats()
        #: errno of what the last run's real-time set-up was refused: mlockall, SCHED_FIFO, CPU affinity (0: ok)
        self.rt_errnos: tuple[int, int, int] = (0, 0, 0)
        self._out = self.ffi.new("hil_core_frame_t *")
        self._replies: deque[Frame] = deque()
        self.lib.hil_core_init()

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
