"""Worker entry points for tests/runlog/test_worker_start.py (importable by a spawned child)."""

from __future__ import annotations

import time
from multiprocessing.connection import Connection
from typing import Any


def spin_then_ready(notices: Connection, status: Connection, ring_path: str, ring_bytes: int,
                    busy_s: float, *_: Any) -> None:
    """Compute for `busy_s` (s of wall time) before reporting ready: a worker whose imports are slow."""
    start = time.monotonic()
    while time.monotonic() - start < busy_s:
        pass
    status.send_bytes(b"R")
    notices.recv_bytes()  # until the client closes the pipe


def sleep_forever(notices: Connection, status: Connection, ring_path: str, ring_bytes: int, *_: Any) -> None:
    """Never report ready and use no CPU: a worker stuck in a blocking call."""
    time.sleep(3600)
