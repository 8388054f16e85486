"""`RunSink`: where each block of the closed loop goes while the run goes on — the window metrics, the
speed-reference check, the live view and the run logger — so nothing of the run has to stay in memory."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from pmsm_hil.hil.metrics.streaming import WindowMetrics
from pmsm_hil.hil.runner.fault_setup import fault_records
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.run_limits import SpeedTail
from pmsm_hil.hil.runner.target_console import TargetConsole
from pmsm_hil.protocol.links.faults import FaultyLink

#: the run's first periods whose execution times are its cold start (first calls: page faults, caches, lazy
#: binding): reported apart as `exec_time_first_us`, left out of `exec_time_us`
COLD_START_PERIODS = 10


class RunSink:
    """Consumes the loop's blocks (`ClosedLoop` BlockSink): period records, raw frames, window trace rows."""

    def __init__(self, cfg: RunConfig, logger: Any, live: Callable[[np.ndarray], None] | None) -> None:
        sc = cfg.scenario
        n_total = round(sc.total_s / cfg.ts_s)
        self.window_start = round(sc.settle_s / cfg.ts_s)
        self.window = WindowMetrics(cfg.machine.layout.trace_dtype)
        self.speed_tail = SpeedTail(self.window_start, n_total - self.window_start)
        self.logger = logger
        self.live = live
        self.log_trace = cfg.log_trace
        self.ts_s = cfg.ts_s
        #: the fault-injecting link (`--fault`), set once installed
        self.faulty: FaultyLink | None = None
        #: period records seen so far
        self.periods_seen = 0
        #: the periods the loop has run so far, read while it runs (the C loop's own counter once it runs;
        #: until then, and for the reference loop, the records seen)
        self.loop_periods: Callable[[], int] = lambda: self.periods_seen
        #: a spawned target's console (its lines go to the log with each block)
        self.console: TargetConsole | None = None
        #: a board's per-period records since the last call (BOARD_DTYPE, to the log with each block)
        self.board_records: Callable[[], np.ndarray] | None = None
        #: execution times [ns] of the run's first `COLD_START_PERIODS` periods
        self.cold_exec_ns: list[int] = []

    def exec_time_first(self) -> dict[str, Any] | None:
        """`{periods, first, max}` [µs]: the execution times of the run's cold start (None: no period ran)."""
        if not self.cold_exec_ns:
            return None
        return {"periods": len(self.cold_exec_ns), "first": self.cold_exec_ns[0] / 1e3,
                "max": max(self.cold_exec_ns) / 1e3}

    def __call__(self, periods: np.ndarray, frames: np.ndarray | None, trace: np.ndarray) -> None:
        first = self.periods_seen
        self.periods_seen += periods.shape[0]
        in_window = max(self.window_start - first, 0)
        if first < COLD_START_PERIODS:
            self.cold_exec_ns += [int(v) for v in periods["exec_time_ns"][: COLD_START_PERIODS - first]]
        if in_window < periods.shape[0]:
            cold = max(COLD_START_PERIODS - (first + in_window), 0)
            self.window.add_periods(periods[in_window:], cold=cold)
        self.window.add_trace(trace)
        self.speed_tail.add(periods, first)
        if self.live is not None:
            self.live(periods)
        faults = fault_records(self.faulty, self.ts_s) if self.faulty is not None else None  # drained always
        logger = self.logger
        if logger is None:
            return
        logger.submit_periods(periods)
        if frames is not None and frames.shape[0]:
            logger.submit_frames(frames)
        if faults is not None:
            logger.submit_faults(faults)
        if self.log_trace and trace.shape[0]:
            logger.submit_trace(trace)
        self.flush_console()

    def flush_console(self) -> None:
        """Give the logger the target's console lines (and a board's period records) that came since the last
        block."""
        if self.console is not None and self.logger is not None:
            lines = self.console.take()
            if lines.shape[0]:
                self.logger.submit_console(lines)
        if self.board_records is not None and self.logger is not None:
            records = self.board_records()
            if records.shape[0]:
                self.logger.submit_board(records)
