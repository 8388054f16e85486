"""`RunLogger`: the runner-side handle of the MCAP logger process.

Each submit copies the block into a shared-memory ring (one memcpy) and sends a 17-byte notice over a
pipe, so the caller's cost is a few µs per 1000-period block plus the copy, and no Python objects are
pickled. The logger process (spawned, or forked from the logger's own fork server: `start_method`) encodes
and writes MCAP; see docs/logging.md. The process, ring and pipes are handled by
`pmsm_hil.hil.runlog.worker_client.WorkerClient`.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from types import TracebackType

import numpy as np

from pmsm_hil.hil.records import FAULT_DTYPE, FRAME_DTYPE, PERIOD_DTYPE, TRACE_DTYPE
from pmsm_hil.hil.runlog import topics
from pmsm_hil.hil.runlog.board_records import BOARD_DTYPE
from pmsm_hil.hil.runlog.console import CONSOLE_DTYPE
from pmsm_hil.hil.runlog.errors import LoggerDiedError, RunLogError
from pmsm_hil.hil.runlog.topics import COMPRESSIONS
from pmsm_hil.hil.runlog.worker_client import START_METHODS, WorkerClient, WorkerTarget, start_failure

DEFAULT_RING_BYTES = 64 * 1024 * 1024
#: the logger process's target (`pmsm_hil.hil.runlog.worker.run_worker`), imported in the logger process only
run_worker = WorkerTarget("pmsm_hil.hil.runlog.worker", "run_worker")


class RunLogger(WorkerClient):
    """Context manager writing period, frame and trace blocks to an MCAP file from a separate process.

    `flush_interval_s` (s): the logger ends its chunk and fsyncs at least this often, so a kill loses
    at most that much. `ring_bytes`: shared buffer between the processes; a submit waits (counted in
    `stall_s`) only if the logger falls this far behind, and raises after `stall_timeout_s`.
    `trace_dtype`: the machine's trace layout (`Machine.layout.trace_dtype`; all float64 fields).
    `start_method`: "spawn" (a new interpreter), "forkserver" (forked from `runlog.fork_server`) or "auto": the
    process's first worker spawned, the later ones forked (≈ 0.2 → 0.015 CPU-s a logger).
    """

    def __init__(
        self,
        path: Path,
        *,
        metadata: Mapping[str, str],
        flush_interval_s: float = 1.0,
        compression: str = "lz4",
        ring_bytes: int = DEFAULT_RING_BYTES,
        start_method: str = "auto",
        start_timeout_s: float = 60.0,
        stall_timeout_s: float = 10.0,
        trace_dtype: np.dtype = TRACE_DTYPE,
    ) -> None:
        super().__init__()
        path = Path(path)
        if not path.parent.is_dir():
            raise RunLogError(f"path: directory {path.parent} does not exist")
        meta = self._check_metadata(metadata)
        if not (isinstance(flush_interval_s, (int, float)) and 0.0 < flush_interval_s <= 3600.0):
            raise RunLogError(f"flush_interval_s: expected 0 < value ≤ 3600 s, got {flush_interval_s!r}")
        if compression not in COMPRESSIONS:
            raise RunLogError(f"compression: expected one of {sorted(COMPRESSIONS)}, got {compression!r}")
        if start_method not in START_METHODS:
            raise RunLogError(f"start_method: expected one of {', '.join(START_METHODS)}, got {start_method!r}")
        names = tuple(trace_dtype.names or ())
        if not names or any(trace_dtype[n] != np.dtype("f8") for n in names):
            raise RunLogError(f"trace_dtype: expected float64 fields, got {trace_dtype}")
        self.path = path
        self.trace_dtype = trace_dtype
        try:
            ready = self._start(run_worker, (str(path), meta, float(flush_interval_s), compression, names),
                                name="hil-runlog", start_method=start_method, ring_bytes=ring_bytes,
                                stall_timeout_s=stall_timeout_s, start_timeout_s=start_timeout_s)
        except OSError as exc:
            raise RunLogError(f"run logger: cannot start the logger process ({exc})") from None
        if ready is None:
            raise LoggerDiedError(self._error or "run logger: process did not start " + start_failure(start_timeout_s))

    @staticmethod
    def _check_metadata(metadata: Mapping[str, str]) -> dict[str, str]:
        if not isinstance(metadata, Mapping):
            raise RunLogError(f"metadata: expected a mapping of str to str, got {type(metadata).__name__}")
        for key, value in metadata.items():
            if not isinstance(key, str) or not isinstance(value, str):
                raise RunLogError(f"metadata[{key!r}]: keys and values must be str, got {value!r}")
        return dict(metadata)

    def _died(self) -> LoggerDiedError:
        self._drain_status()
        self._proc.join(0.5)
        detail = f": {self._error}" if self._error else ""
        return LoggerDiedError(f"run logger: logger process died (exit code {self._proc.exitcode}){detail}")

    def _submit(self, kind: int, block: np.ndarray, dtype: np.dtype, field: str) -> None:
        if self._closed:
            raise RunLogError(f"{field}: logger is closed")
        if not isinstance(block, np.ndarray) or block.dtype != dtype or block.ndim != 1:
            got = getattr(block, "dtype", type(block).__name__)
            raise RunLogError(f"{field}: expected a 1-D array of the record dtype, got {got}")
        if block.shape[0] == 0:
            return
        if self._error is not None or self._status.poll(0):
            raise self._died()
        try:
            self._push(kind, block, dtype.itemsize)
        except OSError:
            raise self._died() from None
        except RunLogError:
            if not self._proc.is_alive():  # it died while the ring was full: say why it died
                raise self._died() from None
            raise

    def submit_periods(self, block: np.ndarray) -> None:
        """Queue a PERIOD_DTYPE block (one MCAP message per period on /periods)."""
        self._submit(topics.KIND_PERIODS, block, PERIOD_DTYPE, "periods")

    def submit_frames(self, block: np.ndarray) -> None:
        """Queue a FRAME_DTYPE block (one MCAP message per frame on /frames)."""
        self._submit(topics.KIND_FRAMES, block, FRAME_DTYPE, "frames")

    def submit_faults(self, block: np.ndarray) -> None:
        """Queue a FAULT_DTYPE block (one MCAP message per injected link fault on /link_faults)."""
        self._submit(topics.KIND_FAULTS, block, FAULT_DTYPE, "faults")

    def submit_console(self, block: np.ndarray) -> None:
        """Queue a CONSOLE_DTYPE block (one MCAP message per target console line on /target/console)."""
        self._submit(topics.KIND_CONSOLE, block, CONSOLE_DTYPE, "console")

    def submit_board(self, block: np.ndarray) -> None:
        """Queue a BOARD_DTYPE block (one MCAP message per control period on /board/periods)."""
        self._submit(topics.KIND_BOARD, block, BOARD_DTYPE, "board")

    def submit_trace(self, block: np.ndarray) -> None:
        """Queue a block of the logger's `trace_dtype` (one CDR message per block on /trace)."""
        self._submit(topics.KIND_TRACE, block, self.trace_dtype, "trace")

    @property
    def pid(self) -> int | None:
        """Process id of the logger process."""
        return self._proc.pid

    def close(self, timeout_s: float = 60.0) -> None:
        """Finalise the file (summary, footer) and stop the logger process; idempotent.

        Raises LoggerDiedError (once) if the logger reported an error or did not end cleanly."""
        if self._closed:
            return
        if not self._stop_worker(topics.KIND_CLOSE, timeout_s):
            self._error = self._error or f"run logger: logger did not finish within {timeout_s} s"
        if self._error is not None:
            raise LoggerDiedError(self._error)
        if self._proc.exitcode != 0:
            raise LoggerDiedError(f"run logger: logger process exit code {self._proc.exitcode}")

    def __enter__(self) -> RunLogger:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
