"""MCAP run logging in a separate process, tolerant reading and repair of cut files."""

from __future__ import annotations

from pmsm_hil.hil.runlog.errors import LoggerDiedError, McapFormatError, RunLogError
from pmsm_hil.hil.runlog.logger import RunLogger
from pmsm_hil.hil.runlog.reader import read_frames, read_metadata, read_periods, read_trace
from pmsm_hil.hil.runlog.repair import RepairReport, repair_mcap

__all__ = [
    "LoggerDiedError",
    "McapFormatError",
    "RepairReport",
    "RunLogError",
    "RunLogger",
    "read_frames",
    "read_metadata",
    "read_periods",
    "read_trace",
    "repair_mcap",
]
