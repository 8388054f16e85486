"""Commands from a CAN log for the offline plant replay (`hil replay CAPTURE.log`, `hil plant replay --input`):
a bench capture (can-utils `candump -L` .log, Vector .asc, .blf, python-can .csv — what `hil mcap export` writes)
read through python-can's log readers, its Command frames (classic parts or CAN FD) assembled by the project's
decoder, in the order captured (`replay_commands.applied_periods` turns them into the periods the loop ran)."""

from __future__ import annotations

import struct
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Final

import can
from can.io.blf import BLFParseError

from pmsm_hil.hil.errors import InputFileError
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


#: what python-can's log readers raise on a corrupt file (a bad header, a broken zlib container, a cut struct,
#: text that is not the format)
_READ_ERRORS: Final = (ValueError, IndexError, TypeError, KeyError, EOFError, struct.error, zlib.error, BLFParseError)
_FORMAT_NAMES: Final = {".log": "candump -L", ".asc": "ASC", ".blf": "BLF", ".csv": "python-can CSV"}


def _check_complete(path: Path) -> None:
    """InputFileError if the log `path` was cut: a BLF whose size or object count differs from its header's, a
    text log (.log, .asc, .csv) whose last line has no end of line, an ASC log without its closing
    `End TriggerBlock` line."""
    if path.suffix.lower() == ".blf":
        return  # checked while reading (`_blf_cut`)
    with path.open("rb") as f:
        size = f.seek(0, 2)
        f.seek(max(0, size - 4096))
        data = f.read()  # the end of the file is enough
    if data and not data.endswith(b"\n"):
        raise InputFileError(f"CAN log {path}: cut: its last line has no end of line")
    if path.suffix.lower() == ".asc":
        lines = [line.strip() for line in data.splitlines() if line.strip()]
        if not lines or not lines[-1].startswith(b"End TriggerBlock"):
            raise InputFileError(f"CAN log {path}: cut: an ASC log ends with 'End TriggerBlock', this one does not")


def _blf_cut(path: Path, reader: can.BLFReader, objects: int) -> str:
    """Why the BLF `path` read by `reader` (`objects` CAN objects yielded) is incomplete, or ''."""
    size = path.stat().st_size
    if reader.file_size != size:
        return f"{size} bytes where its header says {reader.file_size}"
    if reader.object_count and objects > reader.object_count:
        return f"{objects} objects read where its header says {reader.object_count}"
    return ""


def _frames(path: Path) -> Iterator[Frame]:
    try:
        _check_complete(path)
        reader = can.LogReader(path)
    except OSError as exc:
        raise InputFileError(f"CAN log {path}: cannot read: {exc.strerror or exc}") from None
    except InputFileError:
        raise
    except _READ_ERRORS as exc:
        kind = _FORMAT_NAMES.get(path.suffix.lower(), path.suffix)
        raise InputFileError(f"CAN log {path}: not a readable {kind} log: {exc or type(exc).__name__}") from None
    objects = 0
    try:
        for msg in reader:
            objects += 1
            if not (msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id):
                yield Frame(msg.arbitration_id, bytes(msg.data), bool(msg.is_fd))
    except _READ_ERRORS as exc:
        raise InputFileError(f"CAN log {path}: malformed: {exc or type(exc).__name__}") from None
    finally:
        reader.stop()
    if isinstance(reader, can.BLFReader) and (why := _blf_cut(path, reader, objects)):
        raise InputFileError(f"CAN log {path}: cut or corrupt BLF: {why}")


def read_log_commands(path: Path) -> Iterator[Command]:
    """The Commands of the CAN log `path` in the order captured (classic parts or CAN FD, assembled by the project's
    decoder; their seq and contents are checked by `replay_commands.applied_periods`).

    InputFileError (one line) for a log that python-can cannot read (a corrupt BLF container, text that is not
    the format) and a cut log (see `_check_complete`)."""
    from pmsm_hil.protocol.codec import FrameDecoder

    decoder = FrameDecoder(ordered=False)
    for frame in _frames(path):
        msg = decoder.feed(frame)
        if isinstance(msg, Command):
            yield msg


__all__ = ["CAN_LOG_SUFFIXES", "is_can_log", "read_log_commands"]
