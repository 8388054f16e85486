"""`LiveRerun`: the live dashboard, fed from the control loop in blocks and drawn by a separate process.

The loop process only copies each PERIOD_DTYPE block (~1000 periods) into a shared-memory ring and sends
a 17-byte notice (the run logger's mechanism, `pmsm_hil.hil.runlog.ring`); the dashboard process turns
blocks into Rerun columns. Nothing Rerun-related runs, or is even imported, in the loop process.
"""

from __future__ import annotations

import contextlib
import json
import multiprocessing
import time
from multiprocessing.process import BaseProcess
from types import TracebackType
from typing import Any

import numpy as np
from pmsm_hil.dashboards.errors import DashboardError
from pmsm_hil.dashboards.live_worker import KIND_CLOSE, KIND_FLUSH, KIND_PERIODS, NOTICE, run_live_worker
from pmsm_hil.dashboards.recording import RerunTargets
from pmsm_hil.hil.records import PERIOD_DTYPE
from pmsm_hil.hil.runlog.errors import RunLogError
from pmsm_hil.hil.runlog.ring import RingProducer

DEFAULT_RING_BYTES = 32 * 1024 * 1024


class LiveRerun:
    """Live Rerun dashboard of one run. `submit_periods(block)` from the loop; `close()` at the end.

    `vdc` [V], `ts_s` [s], `phases` 3 or 6. `url` is the web-viewer address when serving (else None).
    A submit waits only if the dashboard process falls `ring_bytes` behind (`stall_s` counts it)."""

    def __init__(self, targets: RerunTargets, *, vdc: float, ts_s: float, phases: int = 3, name: str = "",
                 ring_bytes: int = DEFAULT_RING_BYTES, start_timeout_s: float = 60.0,
                 stall_timeout_s: float = 30.0) -> None:
        self._closed = True
        self.final_stats: dict[str, Any] | None = None
        self._error: str | None = None
        self._stall_timeout_s = stall_timeout_s
        self._ring = RingProducer(ring_bytes)
        ctx = multiprocessing.get_context("spawn")
        notice_r, self._notices = ctx.Pipe(duplex=False)
        self._status, status_w = ctx.Pipe(duplex=False)
        settings = {"vdc": float(vdc), "ts_s": float(ts_s), "phases": int(phases), "name": name}
        self._proc: BaseProcess = ctx.Process(
            target=run_live_worker, name="hil-rerun", daemon=True,
            args=(notice_r, status_w, targets, str(self._ring.path), ring_bytes, settings))
        try:
            self._proc.start()
        except OSError as exc:
            self._ring.close()
            raise DashboardError(f"rerun: cannot start the dashboard process ({exc})") from None
        finally:
            notice_r.close()
            status_w.close()
        self._closed = False
        self.url = self._await_ready(start_timeout_s)
        self._ring.unlink()

    def _await_ready(self, timeout_s: float) -> str | None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self._status.poll(0.05):
                msg = self._read_status()
                if msg is not None and msg[:1] == b"R":
                    return msg[1:].decode() or None
                break
            if not self._proc.is_alive():
                break
        self._abort()
        raise DashboardError(self._error or f"rerun: dashboard process did not start within {timeout_s} s")

    def _read_status(self) -> bytes | None:
        try:
            msg = self._status.recv_bytes()
        except (EOFError, OSError):
            return None
        if msg[:1] == b"E":
            self._error = "rerun: " + msg[1:].decode(errors="replace")
        elif msg[:1] == b"D":
            self.final_stats = dict(json.loads(msg[1:]))
        return msg

    def _alive(self) -> bool:
        return self._proc.is_alive()

    def _check(self) -> None:
        while self._status.poll(0):
            if self._read_status() is None:
                break
        if self._error is not None or not self._proc.is_alive():
            error = self._error or f"rerun: dashboard process ended (exit code {self._proc.exitcode})"
            self._abort()
            raise DashboardError(error)

    def submit_periods(self, block: np.ndarray) -> None:
        """Queue a PERIOD_DTYPE block for the dashboard (copied; returns at once)."""
        if self._closed:
            raise DashboardError("rerun: live dashboard is closed")
        if not isinstance(block, np.ndarray) or block.dtype != PERIOD_DTYPE or block.ndim != 1:
            raise DashboardError(f"periods: expected a 1-D PERIOD_DTYPE array, got {getattr(block, 'dtype', block)}")
        if block.shape[0] == 0:
            return
        if self._error is not None or self._status.poll(0):
            self._check()
        payload = np.ascontiguousarray(block).view(np.uint8)
        step = max(1, self._ring.capacity // (4 * PERIOD_DTYPE.itemsize)) * PERIOD_DTYPE.itemsize
        for start in range(0, payload.shape[0], step):
            piece = payload[start:start + step]
            try:
                pos = self._ring.put(piece, self._alive, self._stall_timeout_s)
                self._notices.send_bytes(NOTICE.pack(KIND_PERIODS, pos, piece.shape[0]))
            except (RunLogError, OSError) as exc:
                self._abort()
                raise DashboardError(f"rerun: dashboard process not accepting data ({exc})") from None

    def flush(self, timeout_s: float = 30.0) -> None:
        """Wait until everything submitted has been handed to Rerun's sinks."""
        if self._closed:
            return
        self._notices.send_bytes(NOTICE.pack(KIND_FLUSH, 0, 0))
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self._status.poll(0.05):
                msg = self._read_status()
                if msg is None or msg[:1] in (b"E", b"D"):
                    break
                if msg[:1] == b"F":
                    return
            elif not self._proc.is_alive():
                break
        self._check()
        raise DashboardError(f"rerun: dashboard did not flush within {timeout_s} s")

    @property
    def stall_s(self) -> float:
        """Total time (s) submits waited for ring space."""
        return float(self._ring.stall_s)

    def close(self, timeout_s: float = 60.0) -> None:
        """Flush, finish the .rrd (if any), stop serving and end the dashboard process; idempotent."""
        if self._closed:
            return
        self._closed = True
        with contextlib.suppress(OSError):
            self._notices.send_bytes(NOTICE.pack(KIND_CLOSE, 0, 0))
        self._proc.join(timeout_s)
        self._abort()
        if self._error is not None:
            raise DashboardError(self._error)

    def _abort(self) -> None:
        self._closed = True
        while self._status.poll(0):
            if self._read_status() is None:
                break
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(5.0)
        if self._proc.is_alive():
            self._proc.kill()
            self._proc.join(5.0)
        with contextlib.suppress(OSError):
            self._notices.close()
            self._status.close()
        with contextlib.suppress(Exception):
            self._ring.close()

    def __enter__(self) -> LiveRerun:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
