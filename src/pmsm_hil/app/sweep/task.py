"""What a worker runs: one closed-loop run of a sweep, returned as its result row.

The function is module-level (engines send it by reference) and never raises for a failed run: an error
becomes a row with its end code and reason. Runs in one process are serialised (`_ONE_RUN`): the
in-process virtual bus is process-wide, so a worker process with several threads (a Dask worker started
with `--nthreads 2`) still runs one simulation at a time.
"""

from __future__ import annotations

import os
import socket
import threading
import time
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from pmsm_hil.app.sweep.rows import flatten
from pmsm_hil.app.sweep.runid import canonical_text
from pmsm_hil.hil.errors import InputFileError, ParameterError, PlantFaultError
from pmsm_hil.hil.runner.contract import EndCode
from pmsm_hil.hil.runner.run_config import RunConfig

_ONE_RUN = threading.Lock()


@dataclass(frozen=True, slots=True)
class RunTask:
    """A run as sent to a worker: id, configuration, the configuration columns of its row, the `config`
    text, and the store to log into (STORE/<run id>/run.mcap; None: not logged)."""

    run_id: str
    cfg: RunConfig
    columns: dict[str, Any]
    config: str
    store: str | None = None


def end_code_of(exc: BaseException) -> int:
    """End code of a run that raised: 2 bad configuration, 3 plant fault, 1 anything else."""
    if isinstance(exc, ParameterError | InputFileError):
        return int(EndCode.USAGE_ERROR)
    if isinstance(exc, PlantFaultError):
        return int(EndCode.SAFETY_STOP)
    return int(EndCode.INTERNAL_ERROR)


def run_task(task: RunTask) -> dict[str, Any]:
    """Run `task` and return its row: run_id, end_code, end_reason, the configuration columns, config,
    run_config, every metric flattened (src/pmsm_hil/app/sweep/rows.py), and the run facts host, pid, blas_threads,
    run_wall_s, mcap."""
    from pmsm_hil.hil.runner.run import run_closed_loop

    cfg = task.cfg
    if task.store is not None:
        cfg = replace(cfg, out_dir=Path(task.store) / task.run_id)
    metrics: dict[str, Any] = {}
    mcap: str | None = None
    with _ONE_RUN:
        t0 = time.perf_counter()
        try:
            result = run_closed_loop(cfg)
            metrics = result.metrics
            mcap = None if result.mcap_path is None else str(result.mcap_path)
            code, reason = int(metrics["end_code"]), str(metrics["end_reason"])
        except Exception as exc:  # the worker's boundary: every failure of a run is a row
            code, reason = end_code_of(exc), f"{type(exc).__name__}: {exc}"
        wall = time.perf_counter() - t0
    row = failed_row(task, code, reason)
    for key, value in flatten(metrics).items():
        row.setdefault(key, value)
    row.update(host=socket.gethostname(), pid=os.getpid(), blas_threads=os.environ.get("OPENBLAS_NUM_THREADS"),
               run_wall_s=wall, mcap=mcap)
    return row


def failed_row(task: RunTask, code: int, reason: str) -> dict[str, Any]:
    """A row without metrics: run id, end code and reason, the configuration columns, `config` (the point)
    and `run_config` (the whole canonical configuration, whose hash is the run id)."""
    return {"run_id": task.run_id, "end_code": code, "end_reason": reason, **task.columns, "config": task.config,
            "run_config": canonical_text(task.cfg)}


__all__ = ["RunTask", "end_code_of", "failed_row", "run_task"]
