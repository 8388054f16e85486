"""Commands from a CAN log for the offline plant replay (`hil replay CAPTURE.log`, `hil plant replay --input`):
a bench capture (can-utils `candump -L` .log, Vector .asc, .blf, python-can .csv — what `hil mcap export` writes)
read through python-can's log readers, its Command frames (classic parts or CAN FD) assembled by the project's
decoder, each one period of switching states and durations in the order captured."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Final

import can
from pmsm_hil.hil.errors import InputFileError
from pmsm_hil.hil.machine import THREE_PHASE, MachineLayout
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.messages import Command

#: file suffixes read as CAN logs (python-can's LogReader picks the reader by suffix)
CAN_LOG_SUFFIXES: Final = (".log", ".asc", ".blf")
_PYTHON_CAN_CSV_HEADER: Final = "timestamp,arbitration_id,"


def is_can_log(path: Path) -> bool:
    """True for a CAN log by suffix, or a .csv whose header is python-can's (not a replay CSV)."""
    suffix = path.suffix.lower()
    if suffix in CAN_LOG_SUFFIXES:
        return True
    if suffix != ".csv":
        return False
    try:
        with path.open(encoding="utf-8", errors="replace") as f:
            return f.readline().startswith(_PYTHON_CAN_CSV_HEADER)
    except OSError:
        return False


def _frames(path: Path) -> Iterator[Frame]:
    try:
        reader = can.LogReader(path)
    except (OSError, ValueError) as exc:
        raise InputFileError(f"CAN log {path}: cannot read: {exc}") from None
    try:
        for msg in reader:
            if not (msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id):
                yield Frame(msg.arbitration_id, bytes(msg.data), bool(msg.is_fd))
    except (ValueError, IndexError, TypeError) as exc:
        raise InputFileError(f"CAN log {path}: malformed: {exc}") from None
    finally:
        reader.stop()


def read_log_commands(path: Path, ts_ns: int, *,
                      layout: MachineLayout = THREE_PHASE) -> Iterator[tuple[tuple[int, ...], tuple[int, ...]]]:
    """Yield (states, durations_ns) of each Command in the CAN log `path`, mirrored sequences expanded; a Command
    whose durations do not fill Ts (`ts_ns`) or whose state code exceeds the machine's is an InputFileError
    naming its seq."""
    from pmsm_hil.protocol.codec import FrameDecoder

    decoder = FrameDecoder(ordered=False)
    for frame in _frames(path):
        msg = decoder.feed(frame)
        if not isinstance(msg, Command):
            continue
        states, durations = msg.expanded()
        if abs(sum(durations) - ts_ns) > 1:
            raise InputFileError(f"CAN log {path}: Command seq {msg.seq}: durations sum to {sum(durations)} ns, "
                                 f"expected Ts = {ts_ns} ns (--ts)")
        bad = [s for s in states if not 0 <= s <= layout.max_state_code]
        if bad:
            raise InputFileError(f"CAN log {path}: Command seq {msg.seq}: state code {bad[0]} beyond "
                                 f"0..{layout.max_state_code} ({layout.legs}-phase motor)")
        yield states, durations


__all__ = ["CAN_LOG_SUFFIXES", "is_can_log", "read_log_commands"]
