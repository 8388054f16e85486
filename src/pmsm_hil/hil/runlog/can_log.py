"""A run's /frames as a CAN log through python-can's log writers (`hil mcap export`): candump -L (.log),
Vector ASC (.asc), BLF (.blf) and python-can's CSV, each frame at its virtual time (run time [s], t = 0 at the
first period); frames the host sent (host→target) are written as transmitted, frames it received as received.

What each format keeps of a frame beyond its id, payload and time is `KEEPS` (checked against the installed
python-can by tests/runlog/test_can_log.py): python-can 4.6's candump, ASC and BLF writers and readers round-trip the
FD flag, the bit-rate switch, the error state indicator and the direction; its CSV has none of them (seven columns:
timestamp, arbitration_id, extended, remote, error, dlc, data; its reader reads every row as a received classic
frame)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any, Final

import can
import numpy as np

from pmsm_hil.hil.atomic_write import atomic_path
from pmsm_hil.hil.errors import InputFileError
from pmsm_hil.hil.runlog import topics
from pmsm_hil.hil.runlog.errors import McapFormatError
from pmsm_hil.hil.runlog.reader import ScanState, read_frames

#: --format NAME: python-can writer class; CAN channel the frames are written on
FORMATS: Final[dict[str, tuple[type[Any], str | int]]] = {
    "candump": (can.CanutilsLogWriter, "can0"),
    "asc": (can.ASCWriter, 0),
    "blf": (can.BLFWriter, 0),
    "csv": (can.CSVWriter, "can0"),
}


#: the frame flags each --format keeps through python-can's writer and reader: "fd" (CAN FD), "brs" (bit-rate
#: switch), "esi" (error state indicator), "direction" (Tx/Rx)
FLAGS: Final = ("fd", "brs", "esi", "direction")
KEEPS: Final[dict[str, tuple[str, ...]]] = {"candump": FLAGS, "asc": FLAGS, "blf": FLAGS, "csv": ()}


def frame_messages(frames: np.ndarray, channel: str | int = "can0") -> Iterator[can.Message]:
    """python-can Messages of FRAME_DTYPE records: 11-bit data frames at their virtual time [s], CAN FD frames
    with the bit-rate switch (as the links send them), `is_rx` for target→host frames."""
    for fr in frames:
        fd = bool(fr["is_fd"])
        n = int(fr["length"])
        yield can.Message(timestamp=float(fr["t"]), arbitration_id=int(fr["arbitration_id"]), is_extended_id=False,
                          is_fd=fd, bitrate_switch=fd, data=bytes(fr["data"][:n]), channel=channel,
                          is_rx=int(fr["direction"]) == 1)


def export_frames(mcap: Path, fmt: str, out: Path) -> int:
    """Write the /frames of run log `mcap` to `out` as `fmt` (a FORMATS name); returns the frame count.

    Only a complete run log is exported: a file that is not an MCAP, is cut or corrupt before its data end
    (a failed chunk CRC, a truncated record) or has no /frames channel is a McapFormatError naming the reason,
    and nothing is written (a cut file's valid prefix is recovered by `hil mcap-repair` first). `out` is
    written through a temporary file: a failed export leaves an existing `out` as it was."""
    if fmt not in FORMATS:
        raise InputFileError(f"--format: {fmt!r} is not one of {', '.join(FORMATS)}")
    if not mcap.is_file():
        raise InputFileError(f"RUN.mcap {mcap} does not exist or is not a file")
    state = ScanState()
    frames = read_frames(mcap, state)
    if not state.complete:
        raise McapFormatError(f"RUN.mcap {mcap}: {state.cut_reason(mcap, 'export')}; nothing exported")
    if topics.TOPIC_FRAMES not in state.topics:
        raise McapFormatError(f"RUN.mcap {mcap}: has no {topics.TOPIC_FRAMES} channel (not a run log of `hil run`); "
                              "nothing exported")
    writer_class, channel = FORMATS[fmt]
    with atomic_path(out, option="-o") as tmp:
        try:
            writer = writer_class(tmp)
        except OSError as exc:
            raise InputFileError(f"-o {out}: cannot write: {exc.strerror or exc}") from exc
        try:
            for msg in frame_messages(frames, channel):
                writer.on_message_received(msg)
        finally:
            writer.stop()
    return len(frames)


__all__ = ["FLAGS", "FORMATS", "KEEPS", "export_frames", "frame_messages"]
