"""The pacing the local UDP disturbers (udp_flood.py, udp_spoof.py) share: datagrams at a rate until SIGTERM or a
number of seconds, then "VERB N in T s" printed."""

from __future__ import annotations

import signal
import time
from collections.abc import Callable
from types import FrameType


class Pacer:
    """Installs its SIGTERM handler when made (before the disturber's set-up), so that a SIGTERM at any later moment
    ends `run` with its report instead of killing the process."""

    def __init__(self) -> None:
        self.stopped = False
        signal.signal(signal.SIGTERM, self._on_term)

    def _on_term(self, signum: int, frame: FrameType | None) -> None:
        self.stopped = True

    def run(self, seconds: float, rate: float, sleep_s: float, send: Callable[[int], int], ready: str,
            verb: str) -> int:
        """Print `ready`, then call `send(owed)` (owed: the datagrams due at `rate` [1/s] since the start and not yet
        sent; it returns how many it sent) with `sleep_s` [s] between calls; returns exit code 0."""
        print(ready, flush=True)
        count = 0
        t0 = time.perf_counter()
        while not self.stopped and (now := time.perf_counter() - t0) < seconds:
            count += send(int(now * rate) - count)
            time.sleep(sleep_s)
        print(f"{verb} {count} in {time.perf_counter() - t0:.3f} s", flush=True)
        return 0
