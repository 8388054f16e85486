"""Where the run logger's limit is: period records (and the frames a logged in-process run records with them)
fed to a `RunLogger` as fast as it takes them, in blocks of the C loop's size, timed from the first block to the
closed MCAP file. A loop producing periods faster than this for longer than the logger's ring holds (64 MB)
waits for the logger (lockstep: it slows down, every period still logged; real time: periods start late), so
the figure is the ceiling of `hil run` with logging at any Ts."""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from pmsm_hil.hil.records import FRAME_DTYPE, PERIOD_DTYPE
from pmsm_hil.hil.runlog.logger import RunLogger

#: periods per block (= NL_BLOCK, what the C loop hands over at once)
BLOCK = 1000
#: frames a logged period records (a Measurement and a Command, CAN FD)
FRAMES_PER_PERIOD = 2


@dataclass(frozen=True)
class LoggerLimit:
    """Periods per second the logger wrote (periods and their frames), the time the feeder waited for ring
    space [s], and the MCAP size per period [B]."""

    periods_per_s: float
    stall_s: float
    bytes_per_period: float


def logger_limit(periods: int = 200_000) -> LoggerLimit:
    """Feed `periods` synthetic period records (and their frames) to a RunLogger writing to a temporary folder."""
    block = np.zeros(BLOCK, dtype=PERIOD_DTYPE)
    block["t"] = np.arange(BLOCK) * 25e-6
    block["i_a"] = np.sin(np.arange(BLOCK) * 0.1)  # not all zeros: lz4 must work a little, as on real records
    frames = np.zeros(BLOCK * FRAMES_PER_PERIOD, dtype=FRAME_DTYPE)
    with tempfile.TemporaryDirectory(prefix="hil-logger-limit-") as tmp:
        path = Path(tmp) / "run.mcap"
        logger = RunLogger(path, metadata={"bench": "logger_limit"})
        t0 = time.perf_counter()
        for k in range(periods // BLOCK):
            block["seq"] = np.arange(k * BLOCK, (k + 1) * BLOCK)
            logger.submit_periods(block)
            logger.submit_frames(frames)
        stall = logger.stall_s
        logger.close()
        wall = time.perf_counter() - t0
        size = path.stat().st_size
    n = (periods // BLOCK) * BLOCK
    return LoggerLimit(n / wall, stall, size / n)
