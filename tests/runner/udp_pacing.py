"""The pacing the local UDP disturbers (udp_flood.py, udp_spoof.py) share: a step called over and over until
SIGTERM or a number of seconds, then "VERB N in T s" printed (N: what the last step returned)."""

from __future__ import annotations

import signal
import time
from collections.abc import Callable
from types import FrameType


class Pacer:
    """Installs its SIGTERM handler when made (before the disturber says it is ready), so that a SIGTERM at any
    later moment ends `run` with its report instead of killing the process."""

    def __init__(self) -> None:
        self.stopped = False
        signal.signal(signal.SIGTERM, self._on_term)

    def _on_term(self, signum: int, frame: FrameType | None) -> None:
        self.stopped = True

    def run(self, seconds: float, sleep_s: float, step: Callable[[float], int], verb: str) -> int:
        """Call `step(now)` (now: seconds since the start) with `sleep_s` [s] between calls; returns exit code 0."""
        count = 0
        t0 = time.perf_counter()
        while not self.stopped and (now := time.perf_counter() - t0) < seconds:
            count = step(now)
            time.sleep(sleep_s)
        print(f"{verb} {count} in {time.perf_counter() - t0:.3f} s", flush=True)
        return 0
