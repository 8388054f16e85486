"""The live status line of long commands on a terminal (`hil run`, `hil replay`, `hil bench`, `hil fw build`): one
tqdm line on stderr, redrawn in place at least twice a second (the wall clock moves while the work is silent, e.g.
while a QEMU target boots), with the phase on its left, a bar and counts when the total is known, and the command's
own figures on its right; warnings are printed above it as they happen. Shown only when stdout and stderr are both
terminals and `--quiet` is not given: a pipe, a file or CI gets nothing extra."""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import TracebackType
from typing import Any, TextIO

#: how often the line is redrawn while nothing else moves it [s]
REFRESH_S = 0.25
#: the bar's layout with a known total, and without one (tqdm's format fields)
BAR_FORMAT = "{desc}: {percentage:3.0f}%|{bar:12}| {n_fmt}/{total_fmt} {unit} [{elapsed}<{remaining}]{postfix}"
PHASE_FORMAT = "{desc} [{elapsed}]{postfix}"


def status_wanted(quiet: bool = False, out: TextIO | None = None, err: TextIO | None = None) -> bool:
    """A status line is drawn: not `quiet`, and stdout and stderr are both terminals."""
    if quiet:
        return False
    for stream in (out or sys.stdout, err or sys.stderr):
        isatty = getattr(stream, "isatty", None)
        try:
            if isatty is None or not isatty():
                return False
        except ValueError:  # a closed stream
            return False
    return True


class StatusLine:
    """A live status line (tqdm on stderr), or nothing at all when not `enabled`: every method is then a no-op.

    `phase(text)` names what is being done now; `total(n, unit)` turns on the bar; `update(n, postfix)` moves it
    and sets the figures on the right; `warn(line)` prints a warning above the line at once. A thread redraws the
    line every REFRESH_S so its clock moves while nothing else does. While it is drawn, what the command prints
    on stdout and stderr goes above it, line by line (tqdm's DummyTqdmFile). Use it as a context manager
    (`close`)."""

    def __init__(self, label: str, *, enabled: bool, stream: TextIO | None = None) -> None:
        self.label = label
        self.enabled = enabled
        self._bar: Any = None
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._ticker: threading.Thread | None = None
        self._redirect = contextlib.ExitStack()
        #: called by the redraw thread before each redraw (a command reading a live counter), outside the lock
        self.poll: Callable[[], None] | None = None
        if not enabled:
            return
        from tqdm import tqdm
        from tqdm.contrib import DummyTqdmFile

        _stop_early()
        self._stream = stream or sys.stderr
        self._bar = tqdm(total=None, desc=f"{label}: starting", bar_format=PHASE_FORMAT, file=self._stream,
                         dynamic_ncols=True, leave=True, mininterval=0.0)
        self._redirect.enter_context(contextlib.redirect_stdout(DummyTqdmFile(sys.stdout)))
        self._redirect.enter_context(contextlib.redirect_stderr(DummyTqdmFile(sys.stderr)))
        self._ticker = threading.Thread(target=self._tick, name="hil-status-line", daemon=True)
        self._ticker.start()

    def _tick(self) -> None:
        while not self._stop.wait(REFRESH_S):
            poll = self.poll
            if poll is not None:
                with contextlib.suppress(Exception):  # a display: never the command's failure
                    poll()
            with self._lock:
                if self._bar is not None:
                    self._bar.refresh()

    def phase(self, text: str) -> None:
        """What is being done now (`starting target…`, `running`, `writing outputs`), drawn at once."""
        with self._lock:
            if self._bar is not None:
                self._bar.set_description_str(f"{self.label}: {text}", refresh=True)

    def total(self, n: int, unit: str) -> None:
        """The work has `n` steps of `unit` (periods, runs, builds): the bar and the counts are shown."""
        with self._lock:
            if self._bar is not None:
                self._bar.total = n
                self._bar.unit = unit
                self._bar.bar_format = BAR_FORMAT
                self._bar.refresh()

    def update(self, done: int | None = None, postfix: str | None = None) -> None:
        """Steps done so far (absolute) and the figures on the right (`None`: unchanged)."""
        with self._lock:
            bar = self._bar
            if bar is None:
                return
            if postfix is not None:
                bar.set_postfix_str(postfix, refresh=False)
            if done is not None and done > bar.n:
                bar.update(done - bar.n)
            else:
                bar.refresh()

    def warn(self, line: str) -> None:
        """A warning printed above the status line now (`hil: warning: ...`)."""
        if self._bar is None:
            return
        from tqdm import tqdm

        with self._lock:
            tqdm.write(f"hil: warning: {line}", file=self._stream)

    def close(self, final: str | None = None, *, keep: bool = True) -> None:
        """Stop redrawing; the line stays with `final` as its phase (None: the last one), or is erased
        (`keep=False`: the error message that follows says it all)."""
        self._stop.set()
        if self._ticker is not None:
            self._ticker.join(timeout=2.0)
        self._redirect.close()  # what was printed without a final newline goes out now
        with self._lock:
            bar, self._bar = self._bar, None
            if bar is not None:
                if final is not None:
                    bar.set_description_str(f"{self.label}: {final}", refresh=False)
                bar.leave = keep
                bar.close()

    def __enter__(self) -> StatusLine:
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        if kind is None or issubclass(kind, KeyboardInterrupt):
            self.close("interrupted" if kind is not None else None)
        else:
            self.close(keep=False)


#: the `early_status` line being drawn (its ticker stops when a StatusLine takes over or it is erased)
_early: list[tuple[threading.Event, threading.Lock]] = []


def early_status(label: str, *, quiet: bool = False) -> Callable[[], None]:
    """Draw `LABEL: starting… N s` at once, before the command's imports (seconds on a loaded machine), where a
    status line is wanted, its clock moving every REFRESH_S; the command's `StatusLine` stops it and draws over
    it. Returns what erases it (the command ended before drawing its own: a usage error)."""
    if not status_wanted(quiet):
        return lambda: None
    stream = sys.stderr
    stop = threading.Event()
    lock = threading.Lock()
    t0 = time.monotonic()
    stream.write(f"{label}: starting…")
    stream.flush()

    def tick() -> None:
        while not stop.wait(REFRESH_S):
            with lock:
                if stop.is_set():
                    return
                stream.write(f"\r{label}: starting… {time.monotonic() - t0:.0f} s")
                stream.flush()

    threading.Thread(target=tick, name="hil-early-status", daemon=True).start()
    _early.append((stop, lock))

    def erase() -> None:
        with lock:
            if stop.is_set():
                return
            stop.set()
            stream.write("\r\x1b[2K")
            stream.flush()
    return erase


def _stop_early() -> None:
    """A StatusLine takes the line over: the early one stops drawing."""
    while _early:
        stop, lock = _early.pop()
        with lock:
            stop.set()


@contextmanager
def status_line(label: str, *, quiet: bool = False) -> Iterator[StatusLine]:
    """A `StatusLine` for `label`, drawn when `status_wanted(quiet)`."""
    with StatusLine(label, enabled=status_wanted(quiet)) as line:
        yield line


__all__ = ["StatusLine", "early_status", "status_line", "status_wanted"]
