"""Main function of the live-dashboard process: period blocks from the ring → `PeriodStreamer` → Rerun.

Notices from the loop process (struct NOTICE: kind, ring position, bytes): KIND_PERIODS a block,
KIND_FLUSH flush and acknowledge, KIND_CLOSE flush and end. Status to the loop process: b"R" + web URL
(may be empty) when ready, b"F" flushed, b"E" + text on a fatal error, b"D" + JSON counts when done.
SIGINT is ignored (the loop process owns Ctrl-C); EOF on the notice pipe ends the process too.
"""

from __future__ import annotations

import contextlib
import json
import signal
from multiprocessing.connection import Connection
from pathlib import Path
from typing import Any, Final

import numpy as np

from pmsm_hil.dashboards.recording import RerunTargets, flush_recording
from pmsm_hil.hil.records import PERIOD_DTYPE
from pmsm_hil.hil.runlog.channel import NOTICE, send_status
from pmsm_hil.hil.runlog.ring import RingConsumer

KIND_PERIODS: Final = 1
KIND_FLUSH: Final = 8
KIND_CLOSE: Final = 9


def run_live_worker(notices: Connection, status: Connection, ring_path: str, ring_bytes: int,
                    targets: RerunTargets, settings: dict[str, Any]) -> None:
    """Live-dashboard process entry point (see module docstring)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        from pmsm_hil.dashboards.blueprint import build_blueprint
        from pmsm_hil.dashboards.recording import open_recording
        from pmsm_hil.dashboards.streamer import PeriodStreamer

        ring = RingConsumer(Path(ring_path), ring_bytes)
        rec, url = open_recording(targets, build_blueprint(phases=settings["phases"], vdc=settings["vdc"]))
        if settings.get("name"):
            rec.send_recording_name(settings["name"])
        streamer = PeriodStreamer(rec, vdc=settings["vdc"], ts_s=settings["ts_s"], legs=settings["phases"])
    except Exception as exc:  # report setup failures to the loop process instead of a traceback
        send_status(status, b"E" + f"{type(exc).__name__}: {exc}".encode())
        return
    send_status(status, b"R" + (url or "").encode())
    reason = "close"
    try:
        while True:
            try:
                kind, pos, nbytes = NOTICE.unpack(notices.recv_bytes())
            except (EOFError, OSError):
                reason = "eof"
                break
            if kind == KIND_PERIODS:
                streamer.send_block(np.frombuffer(ring.take(pos, nbytes), dtype=PERIOD_DTYPE))
            elif kind == KIND_FLUSH:
                flush_recording(rec)
                send_status(status, b"F")
            elif kind == KIND_CLOSE:
                break
        flush_recording(rec)
    except Exception as exc:
        reason = "error"
        send_status(status, b"E" + f"live dashboard: {type(exc).__name__}: {exc}".encode())
    finally:
        ring.close()
    send_status(status, b"D" + json.dumps({"periods": streamer.periods, "reason": reason}).encode())
    with contextlib.suppress(Exception):
        rec.disconnect()
