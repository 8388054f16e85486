"""Single-producer single-consumer byte ring in shared memory (a file in /dev/shm mapped by both processes).

The producer (runner, numpy arrays) copies a block into the ring and sends a small notice (kind, position, length) over
a pipe; the consumer (logger process) copies the block out and publishes its consumed position in the
8-byte control word at the start of the mapping. Positions are monotonically increasing byte counts;
a block never wraps (the producer skips the tail end of the ring instead). The consumer uses `memoryview`s
only: the logger process does not import numpy to take its blocks. The backing file is unlinked
as soon as both sides have mapped it, so nothing is left behind if either process is killed.
"""

from __future__ import annotations

import contextlib
import mmap
import os
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Final

from pmsm_hil.hil.runlog.errors import RunLogError

if TYPE_CHECKING:
    import numpy as np

HEADER_BYTES: Final = 64
_SHM_DIR: Final = Path("/dev/shm")


def _map_fd(fd: int, size: int) -> mmap.mmap:
    try:
        return mmap.mmap(fd, size)
    finally:
        os.close(fd)


class RingProducer:
    """Runner side: creates the ring (`capacity` bytes) and copies blocks into it."""

    def __init__(self, capacity: int) -> None:
        if capacity < 4096:
            raise RunLogError(f"ring_bytes: expected ≥ 4096, got {capacity}")
        directory = _SHM_DIR if _SHM_DIR.is_dir() else Path(tempfile.gettempdir())
        fd, name = tempfile.mkstemp(prefix="hil-runlog-", suffix=".ring", dir=directory)
        self.path = Path(name)
        self.capacity = capacity
        try:
            os.ftruncate(fd, HEADER_BYTES + capacity)
        except OSError as exc:
            os.close(fd)
            self.unlink()
            raise RunLogError(f"ring_bytes: cannot size the shared ring ({exc})") from None
        import numpy as np  # the runner's side: numpy is loaded there anyway

        self._mm = _map_fd(fd, HEADER_BYTES + capacity)
        self._ctrl = np.frombuffer(self._mm, dtype=np.uint64, count=1)
        self._data = np.frombuffer(self._mm, dtype=np.uint8, count=capacity, offset=HEADER_BYTES)
        self._data[:] = 0  # touch every page now, not inside the runner's loop
        self._head = 0
        self.stall_s: float = 0.0

    def unlink(self) -> None:
        """Remove the backing file name (the mapping stays valid)."""
        with contextlib.suppress(FileNotFoundError):
            os.unlink(self.path)

    def put(self, payload: np.ndarray, is_alive: Callable[[], bool], timeout_s: float) -> int:
        """Copy the uint8 array `payload` into the ring; return its position. Waits for space (busy-poll
        with short sleeps) while `is_alive()`; raises RunLogError if no space appears within `timeout_s`."""
        n = payload.shape[0]
        if n > self.capacity:
            raise RunLogError(f"block: {n} bytes exceed the ring capacity {self.capacity}")
        pos = self._head
        offset = pos % self.capacity
        if offset + n > self.capacity:
            pos += self.capacity - offset
            offset = 0
        if pos + n - int(self._ctrl[0]) > self.capacity:
            self._wait(pos + n - self.capacity, is_alive, timeout_s)
        self._data[offset : offset + n] = payload
        self._head = pos + n
        return pos

    def _wait(self, needed_tail: int, is_alive: Callable[[], bool], timeout_s: float) -> None:
        start = time.perf_counter()
        while int(self._ctrl[0]) < needed_tail:
            now = time.perf_counter()
            if not is_alive():
                self.stall_s += now - start
                raise RunLogError("run logger: logger process is gone while waiting for ring space")
            if now - start > timeout_s:
                self.stall_s += now - start
                raise RunLogError(f"run logger: no ring space freed for {timeout_s:.3g} s (logger stuck)")
            time.sleep(0.0002)
        self.stall_s += time.perf_counter() - start

    def close(self) -> None:
        """Unmap the ring and remove its file."""
        self.unlink()
        del self._ctrl, self._data
        self._mm.close()


class RingConsumer:
    """Logger side: maps the ring created by `RingProducer` and takes blocks out of it."""

    def __init__(self, path: Path, capacity: int) -> None:
        self.capacity = capacity
        self._mm = _map_fd(os.open(path, os.O_RDWR), HEADER_BYTES + capacity)
        with contextlib.suppress(FileNotFoundError):
            os.unlink(path)
        view = memoryview(self._mm)
        self._ctrl = view[:8].cast("Q")  # native uint64, as the producer reads it
        self._data = view[HEADER_BYTES : HEADER_BYTES + capacity]

    def take(self, pos: int, n: int) -> bytes:
        """Copy out the block at `pos` (`n` bytes) and release its space to the producer."""
        offset = pos % self.capacity
        if n > self.capacity or offset + n > self.capacity:
            raise RunLogError(f"ring notice: block at {pos} of {n} bytes does not fit the ring")
        data = self._data[offset : offset + n].tobytes()
        self._ctrl[0] = pos + n
        return data

    def close(self) -> None:
        """Unmap the ring."""
        self._ctrl.release()
        self._data.release()
        self._mm.close()
