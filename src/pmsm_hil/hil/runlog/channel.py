"""Wire format between a `WorkerClient` and its worker process (run logger, live dashboard).

Notices, client → worker over a pipe: NOTICE = (kind, ring position, bytes); the kinds belong to each
worker. Status, worker → client: one message each, first byte b"R" ready (+ worker-specific text),
b"E" + text fatal error, b"D" + JSON final statistics; a worker may add its own (the dashboard's b"F").
"""

from __future__ import annotations

import contextlib
import struct
from multiprocessing.connection import Connection
from typing import Final

NOTICE: Final = struct.Struct("<BQQ")


def send_status(conn: Connection, payload: bytes) -> None:
    """Send one status message; silently nothing if the client is gone (nobody left to tell)."""
    with contextlib.suppress(OSError):
        conn.send_bytes(payload)
