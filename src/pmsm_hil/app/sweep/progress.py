"""A progress line with the ETA on stderr: rewritten in place on a terminal, else a line every few seconds."""

from __future__ import annotations

import sys
import time
from typing import TextIO


def _clock(seconds: float) -> str:
    s = max(0, round(seconds))
    h, rest = divmod(s, 3600)
    return f"{h}:{rest // 60:02d}:{rest % 60:02d}" if h else f"{rest // 60}:{rest % 60:02d}"


class Progress:
    """`done/total runs, failed, elapsed, ETA`; runs finished by an earlier sweep count as done but not
    in the rate. `quiet`: prints nothing."""

    #: least time between two lines when stderr is not a terminal [s]
    PLAIN_EVERY_S = 5.0

    def __init__(self, total: int, already: int, *, quiet: bool = False, stream: TextIO | None = None,
                 label: str = "sweep") -> None:
        self.total, self.already, self.label = total, already, label
        self.new = self.failed = 0
        self.quiet = quiet
        self.stream = stream or sys.stderr
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())
        self.t0 = time.monotonic()
        self._last = -1e9

    def line(self) -> str:
        done = self.already + self.new
        elapsed = time.monotonic() - self.t0
        left = self.total - done
        eta = "?" if not self.new else _clock(elapsed / self.new * left)
        width = 20
        filled = round(width * done / self.total) if self.total else width
        bar = "#" * filled + "." * (width - filled)
        failed = f", {self.failed} failed" if self.failed else ""
        skipped = f" ({self.already} done before)" if self.already else ""
        return (f"{self.label} [{bar}] {done}/{self.total} runs{skipped}{failed}, elapsed {_clock(elapsed)}, "
                f"ETA {eta if left else '0:00'}")

    def update(self, failed: bool) -> None:
        """One more run finished (`failed`: it did not complete)."""
        self.new += 1
        self.failed += int(failed)
        self.show()

    def show(self, final: bool = False) -> None:
        if self.quiet:
            return
        now = time.monotonic()
        if self.tty:
            self.stream.write("\r\x1b[2K" + self.line() + ("\n" if final else ""))
        elif final or now - self._last >= self.PLAIN_EVERY_S:
            self.stream.write(self.line() + "\n")
        else:
            return
        self._last = now
        self.stream.flush()


__all__ = ["Progress"]
