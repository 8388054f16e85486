"""`deferred_interrupts`: Ctrl-C and SIGTERM recorded instead of raised while a run's loop and outputs are written.

A KeyboardInterrupt raised between two bytecodes can cut a block between the loop and the logger (a drained
ring slot never handed on, a record packed but not counted): the log then misses periods that metrics.json
counts. Inside `deferred_interrupts()` the signal only sets a flag and calls the hooks (the C loop's
`nl_stop`); the loop ends at the next period boundary, drains every block and the run writes its outputs.
"""

from __future__ import annotations

import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from types import FrameType


class StopRequest:
    """Whether SIGINT/SIGTERM arrived (`signum`), and the hooks to call when one does."""

    def __init__(self) -> None:
        #: the signal that asked the run to stop, None while none did
        self.signum: int | None = None
        #: truthy once a stop was asked (a list: one cheap truth test per period in the Python loop)
        self.flag: list[int] = []
        self._hooks: list[Callable[[], None]] = []

    @property
    def requested(self) -> bool:
        """True once SIGINT or SIGTERM arrived."""
        return bool(self.flag)

    def request(self, signum: int) -> None:
        """Record a stop (the signal handler) and call every hook."""
        if self.signum is None:
            self.signum = signum
        self.flag.append(signum)
        for hook in list(self._hooks):
            hook()

    @contextmanager
    def hook(self, fn: Callable[[], None]) -> Iterator[None]:
        """Call `fn` on a stop while inside (at once if one was already asked)."""
        self._hooks.append(fn)
        try:
            if self.flag:
                fn()
            yield
        finally:
            self._hooks.remove(fn)


_current: StopRequest | None = None


@contextmanager
def deferred_interrupts() -> Iterator[StopRequest]:
    """SIGINT and SIGTERM set the yielded `StopRequest` instead of raising, where they would raise (a Python
    handler in place: Ctrl-C's default, `hil run`'s SIGTERM); an ignored or default-action signal is left as
    it is (sweep workers). Nested uses share the outermost request; off the main thread nothing is installed
    (signals reach only the main thread)."""
    global _current
    if _current is not None:
        yield _current
        return
    req = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield req
        return

    def handler(signum: int, frame: FrameType | None) -> None:
        req.request(signum)

    previous: dict[int, signal.Handlers | Callable[[int, FrameType | None], object] | int | None] = {}
    try:
        for sig in (signal.SIGINT, signal.SIGTERM):
            old = signal.getsignal(sig)
            if callable(old):
                previous[sig] = signal.signal(sig, handler)
        _current = req
        yield req
    finally:
        _current = None
        for signum, handler_before in previous.items():
            signal.signal(signum, handler_before)
