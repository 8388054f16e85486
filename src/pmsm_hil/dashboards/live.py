"""`LiveRerun`: the live dashboard, fed from the control loop in blocks and drawn by a separate process.

The loop process only copies each PERIOD_DTYPE block (~1000 periods) into a shared-memory ring and sends
a 17-byte notice (the run logger's mechanism, `pmsm_hil.hil.runlog.ring`); the dashboard process turns
blocks into Rerun columns. Nothing Rerun-related runs, or is even imported, in the loop process.
"""

from __future__ import annotations

import time
from types import TracebackType

import numpy as np

from pmsm_hil.dashboards.errors import DashboardError
from pmsm_hil.dashboards.live_worker import KIND_CLOSE, KIND_FLUSH, KIND_PERIODS, run_live_worker
from pmsm_hil.dashboards.recording import RerunTargets
from pmsm_hil.hil.records import PERIOD_DTYPE
from pmsm_hil.hil.runlog.channel import NOTICE
from pmsm_hil.hil.runlog.errors import RunLogError
from pmsm_hil.hil.runlog.worker_client import WorkerClient, start_failure

DEFAULT_RING_BYTES = 32 * 1024 * 1024


class LiveRerun(WorkerClient):
    """Live Rerun dashboard of one run. `submit_periods(block)` from the loop; `close()` at the end.

    `vdc` [V], `ts_s` [s], `phases` 3 or 6. `url` is the web-viewer address when serving (else None).
    A submit waits only if the dashboard process falls `ring_bytes` behind (`stall_s` counts it)."""

    _error_prefix = "rerun: "

    def __init__(self, targets: RerunTargets, *, vdc: float, ts_s: float, phases: int = 3, name: str = "",
                 ring_bytes: int = DEFAULT_RING_BYTES, start_timeout_s: float = 60.0,
                 stall_timeout_s: float = 30.0) -> None:
        super().__init__()
        settings = {"vdc": float(vdc), "ts_s": float(ts_s), "phases": int(phases), "name": name}
        try:
            ready = self._start(run_live_worker, (targets, settings), name="hil-rerun", start_method="spawn",
                                ring_bytes=ring_bytes, stall_timeout_s=stall_timeout_s, start_timeout_s=start_timeout_s)
        except OSError as exc:
            raise DashboardError(f"rerun: cannot start the dashboard process ({exc})") from None
        if ready is None:
            raise DashboardError(self._error
                                 or "rerun: dashboard process did not start " + start_failure(start_timeout_s))
        self.url = ready.decode() or None

    def _check(self) -> None:
        self._drain_status()
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
        try:
            self._push(KIND_PERIODS, block, PERIOD_DTYPE.itemsize)
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

    def close(self, timeout_s: float = 60.0) -> None:
        """Flush, finish the .rrd (if any), stop serving and end the dashboard process; idempotent."""
        if self._closed:
            return
        self._stop_worker(KIND_CLOSE, timeout_s)
        if self._error is not None:
            raise DashboardError(self._error)

    def __enter__(self) -> LiveRerun:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
