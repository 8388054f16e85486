"""What a spawned target process writes (a SIL firmware's `printf`, `hil target`'s own lines), drained all the
time: a target never blocks on a full pipe (a firmware printing ~110 bytes per step filled the 64 KiB pipe in
610 periods and was then taken for a silent one).

One thread per stream reads lines as they come. On stdout, `hil target`'s "ready" line, a SIL target's "sil
initialised" line and its last "link stats:" line are the runner's; every other line, and every stderr line, is
console output: queued for the run's log (`/target/console` in the MCAP, `CONSOLE_DTYPE`, at most `MAX_LINES`
lines of `MAX_LINE_BYTES` bytes per run, the rest counted), printed on the terminal with `--verbose`, and the
last stderr lines kept for an error.
"""

from __future__ import annotations

import collections
import sys
import threading
import time
from typing import IO

import numpy as np

from pmsm_hil.hil.runlog.console import CONSOLE_DTYPE, MAX_LINE_BYTES, STREAM_STDERR, STREAM_STDOUT
from pmsm_hil.sim_target.process import SIL_INIT_LINE

#: console lines of one run kept for the log (a firmware printing every step would fill the disk)
MAX_LINES = 100_000
#: stderr lines kept for an error message
TAIL_LINES = 50


class TargetConsole:
    """Drains a target process's stdout and stderr (binary pipes) from two daemon threads."""

    def __init__(self, stdout: IO[bytes] | None, stderr: IO[bytes] | None, *, ready_prefix: str,
                 stats_prefix: str, init_line: str = SIL_INIT_LINE, verbose: bool = False) -> None:
        self._ready_prefix = ready_prefix.encode()
        self._init_line = init_line.encode()
        #: set once a SIL target process said its firmware's hil_app_init returned
        self.initialised = threading.Event()
        self._stats_prefix = stats_prefix.encode()
        self.verbose = verbose
        self._lock = threading.Lock()
        self._pending: list[tuple[float, int, bytes]] = []
        self._t0 = time.monotonic()
        self.ready = threading.Event()
        #: the "ready" line, "" until it came
        self.ready_line = ""
        #: the last "link stats:" line (without its prefix), "" if none
        self.stats_line = ""
        #: console lines seen, and those beyond MAX_LINES (counted, not logged)
        self.lines = 0
        self.dropped = 0
        self._tail: collections.deque[str] = collections.deque(maxlen=TAIL_LINES)
        streams = ((stdout, STREAM_STDOUT, "stdout"), (stderr, STREAM_STDERR, "stderr"))
        self._threads = [threading.Thread(target=self._read, args=(stream, kind), daemon=True,
                                          name=f"hil-target-{name}")
                         for stream, kind, name in streams if stream is not None]
        for thread in self._threads:
            thread.start()

    def _read(self, stream: IO[bytes], kind: int) -> None:
        try:
            for raw in iter(stream.readline, b""):
                self._line(raw.rstrip(b"\r\n"), kind)
        except (OSError, ValueError):  # the stream closed under the thread
            pass
        finally:
            if kind == STREAM_STDOUT:
                self.ready.set()  # end of file: nobody waits for a line that cannot come

    def _line(self, line: bytes, kind: int) -> None:
        if kind == STREAM_STDOUT and not self.ready_line and line.startswith(self._ready_prefix):
            self.ready_line = line.decode(errors="replace")
            self.ready.set()
            return
        if kind == STREAM_STDOUT and line == self._init_line and not self.initialised.is_set():
            self.initialised.set()
            return
        if kind == STREAM_STDOUT and line.startswith(self._stats_prefix):
            self.stats_line = line[len(self._stats_prefix):].decode(errors="replace")
            return
        text = line.decode(errors="replace")
        if kind == STREAM_STDERR:
            self._tail.append(text)
        if self.verbose:
            print(f"[target] {text}", file=sys.stderr, flush=True)
        with self._lock:
            self.lines += 1
            if self.lines > MAX_LINES:
                self.dropped += 1
            else:
                self._pending.append((time.monotonic() - self._t0, kind, line[:MAX_LINE_BYTES]))

    def feed(self, text: str, kind: int = STREAM_STDERR) -> None:
        """Take `text` as console lines of stream `kind` (a console read from a file: QEMU's)."""
        for line in text.splitlines():
            self._line(line.encode(errors="replace"), kind)

    def wait_ready(self, timeout_s: float) -> bool:
        """Wait up to `timeout_s` for the ready line: True when it came (False: timeout or end of file)."""
        self.ready.wait(timeout_s)
        return bool(self.ready_line)

    def stderr_text(self) -> str:
        """The last stderr lines, joined."""
        return "\n".join(self._tail).strip()

    def join(self, timeout_s: float = 1.0) -> None:
        """Wait for the readers to reach end of file (the process ended)."""
        deadline = time.monotonic() + timeout_s
        for thread in self._threads:
            thread.join(max(deadline - time.monotonic(), 0.0))

    def take(self) -> np.ndarray:
        """The console lines queued since the last call as CONSOLE_DTYPE records (t: seconds since the process
        was started, seq: the line's number in the run)."""
        with self._lock:
            pending, self._pending = self._pending, []
            first = self.lines - self.dropped - len(pending)
        out = np.zeros(len(pending), dtype=CONSOLE_DTYPE)
        for i, (t, kind, line) in enumerate(pending):
            out[i] = (t, first + i, kind, len(line), line)
        return out
