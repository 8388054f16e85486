"""MCAP run logging in a separate process, tolerant reading and repair of cut files.

The names below load on first use: the logger process imports the writer's modules only, not the reader's and
the repair's (numpy and mcap's reader stay out of a process that does not read)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from pmsm_hil.lazy_names import lazy_getattr

if TYPE_CHECKING:
    from pmsm_hil.hil.runlog.errors import LoggerDiedError, McapFormatError, RunLogError
    from pmsm_hil.hil.runlog.logger import RunLogger
    from pmsm_hil.hil.runlog.reader import read_frames, read_metadata, read_periods, read_trace
    from pmsm_hil.hil.runlog.repair import RepairReport, repair_mcap

_LAZY = {
    **dict.fromkeys(("LoggerDiedError", "McapFormatError", "RunLogError"), "pmsm_hil.hil.runlog.errors"),
    "RunLogger": "pmsm_hil.hil.runlog.logger",
    **dict.fromkeys(("read_frames", "read_metadata", "read_periods", "read_trace"), "pmsm_hil.hil.runlog.reader"),
    **dict.fromkeys(("RepairReport", "repair_mcap"), "pmsm_hil.hil.runlog.repair"),
}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())


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
