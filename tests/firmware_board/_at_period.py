"""Acting on a C-loop run at a given period: a `counter` hook of `run_closed_loop` that watches the loop's own
period count. The C loop hands its records to `live` only in blocks of 1000 periods, and may run up to its ring
(8000 periods) ahead of them: a test that acts from `live` needs a run ~10 times longer than one acting here."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager


@contextmanager
def at_period(period: int, action: Callable[[int], None]) -> Iterator[Callable[[Callable[[], int]], None]]:
    """A `counter` hook that starts a thread watching the loop's period count (asleep, 1 ms at a time) and calls
    `action(periods run)` once, when the loop has run `period` periods; the watch ends with the `with` block."""
    ended = threading.Event()

    def start(periods: Callable[[], int]) -> None:
        def watch() -> None:
            while not ended.wait(0.001):
                done = periods()
                if done >= period:
                    action(done)
                    return

        threading.Thread(target=watch, name=f"at-period-{period}", daemon=True).start()

    try:
        yield start
    finally:
        ended.set()
