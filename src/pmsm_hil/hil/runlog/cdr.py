"""Fixed-size ROS 2 CDR messages of `/periods` and `/frames` (schema encoding `ros2msg`, message encoding `cdr`).

One message per record, every message of a topic the same size: a 4-byte encapsulation header (CDR little
endian), then the fields in order, each primitive aligned to its size relative to the end of the header,
fixed-size arrays (`uint8[3] states`) without a length prefix. A block of messages is thus one numpy
structured array (`CdrMessage.dtype`, explicit offsets), filled field by field from the record block with
no per-record Python; NaN stays NaN. The reader builds the dtype from the file's schema text
(`parse_schema`), so a message is decoded from what the file says, not from what this code writes.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np

from pmsm_hil.hil.records import FRAME_DTYPE, PERIOD_DTYPE
from pmsm_hil.hil.runlog.encoding import UNITS
from pmsm_hil.hil.runlog.errors import McapFormatError

#: numpy layout of each ROS 2 primitive (little endian)
NUMPY_TYPES: Final = {
    "float64": "<f8", "float32": "<f4", "int64": "<i8", "uint64": "<u8", "int32": "<i4", "uint32": "<u4",
    "int16": "<i2", "uint16": "<u2", "int8": "i1", "uint8": "u1", "byte": "u1", "char": "u1", "bool": "?",
}
_ROS_TYPES: Final = {"f8": "float64", "u4": "uint32", "u2": "uint16", "u1": "uint8"}
#: the encapsulation header as a little-endian uint32: representation 0x0001 (CDR_LE), options 0
HEADER_WORD: Final = 0x0100
HEADER_FIELD: Final = "_encapsulation"


@dataclass(frozen=True)
class MsgField:
    """One field of a message: name, ROS 2 primitive type, fixed array length (0: a scalar)."""

    name: str
    ros_type: str
    count: int = 0


@dataclass(frozen=True)
class CdrMessage:
    """A fixed-size message type: its fields, the numpy dtype of one serialised message (header field
    `HEADER_FIELD`, then the fields at their CDR offsets) and its ros2msg schema text."""

    fields: tuple[MsgField, ...]
    dtype: np.dtype
    schema: bytes


def message_type(fields: Sequence[MsgField], title: str, notes: Mapping[str, str] = UNITS,
                 size: int | None = None) -> CdrMessage:
    """The CdrMessage of `fields` (schema: `title` as a comment, `notes[name]` as each field's comment);
    `size` [bytes] overrides the message size (a writer may pad the end)."""
    names, offsets = [HEADER_FIELD], [0]
    formats: list[Any] = ["<u4"]
    pos, lines = 0, [f"# {title}"]
    for f in fields:
        base = np.dtype(NUMPY_TYPES[f.ros_type])
        pos += -pos % base.itemsize
        names.append(f.name)
        formats.append((base, (f.count,)) if f.count else base)
        offsets.append(4 + pos)
        pos += base.itemsize * max(f.count, 1)
        note = f"  # {notes[f.name]}" if f.name in notes else ""
        lines.append(f"{f.ros_type}{f'[{f.count}]' if f.count else ''} {f.name}{note}")
    itemsize = 4 + pos if size is None else size
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets, "itemsize": itemsize})
    return CdrMessage(tuple(fields), dtype, ("\n".join(lines) + "\n").encode())


def fields_of(dtype: np.dtype) -> tuple[MsgField, ...]:
    """A message field per field of the record `dtype`, same names (sub-arrays → fixed arrays)."""
    out = []
    for name in dtype.names or ():
        field = dtype[name]
        out.append(MsgField(name, _ROS_TYPES[field.base.str.lstrip("<|")], field.shape[0] if field.shape else 0))
    return tuple(out)


def parse_schema(schema: bytes, topic: str, size: int | None = None) -> CdrMessage:
    """The CdrMessage a ros2msg schema describes (fixed-size primitives and arrays only; constants skipped;
    McapFormatError otherwise). `size`: the messages' size in bytes, if known."""
    fields: list[MsgField] = []
    for raw in schema.decode("utf-8", errors="replace").splitlines():
        line = raw.split("#", 1)[0].strip()
        if not line or "=" in line:  # blank, comment or constant (no wire bytes)
            continue
        kind, _, rest = line.partition(" ")
        name = rest.split()[0] if rest.split() else ""
        base, bracket, count = kind.partition("[")
        if base not in NUMPY_TYPES or not name.isidentifier() or (bracket and not count[:-1].isdigit()):
            raise McapFormatError(f"{topic}: schema line {raw.strip()!r} is not a fixed-size primitive field")
        fields.append(MsgField(name, base, int(count[:-1]) if bracket else 0))
    if not fields:
        raise McapFormatError(f"{topic}: schema has no fields")
    msg = message_type(fields, "", {})
    if size is not None and size < msg.dtype.itemsize:
        raise McapFormatError(f"{topic}: {size}-byte messages, the schema needs {msg.dtype.itemsize}")
    return msg if size is None else message_type(fields, "", {}, size)


PERIOD_MSG: Final = message_type(fields_of(PERIOD_DTYPE), "pmsm_hil control period (PERIOD_DTYPE), SI units")

FRAME_DATA_BYTES: Final = int(FRAME_DTYPE["data"].shape[0])
#: frame message field → FRAME_DTYPE field, where the names differ
FRAME_RENAMES: Final = {"dir": "direction", "id": "arbitration_id", "fd": "is_fd", "len": "length"}
FRAME_MSG: Final = message_type(
    (MsgField("t", "float64"), MsgField("seq", "uint32"), MsgField("dir", "uint8"), MsgField("id", "uint32"),
     MsgField("fd", "bool"), MsgField("len", "uint8"), MsgField("data", "uint8", FRAME_DATA_BYTES)),
    "pmsm_hil raw link frame (FRAME_DTYPE)",
    {"t": "s (sim time)", "dir": "0 host→target, 1 target→host", "id": "arbitration id",
     "fd": "CAN FD", "len": f"payload bytes: the first len of data count (≤ {FRAME_DATA_BYTES})"},
)


def fill_periods(out: np.ndarray, block: np.ndarray) -> None:
    """Serialise the PERIOD_DTYPE `block` into `out` (PERIOD_MSG.dtype, same length, padding zeroed)."""
    out[HEADER_FIELD] = HEADER_WORD
    for name in PERIOD_DTYPE.names or ():
        out[name] = block[name]


def fill_frames(out: np.ndarray, block: np.ndarray) -> None:
    """Serialise the FRAME_DTYPE `block` into `out` (FRAME_MSG.dtype, padding zeroed); `fd` as 0/1, `len`
    clamped to the data field (as the JSON logs did)."""
    out[HEADER_FIELD] = HEADER_WORD
    for f in FRAME_MSG.fields:
        out[f.name] = block[FRAME_RENAMES.get(f.name, f.name)]
    out["len"] = np.minimum(block["length"], FRAME_DATA_BYTES)


def decode(messages: Sequence[bytes], msg: CdrMessage, dtype: np.dtype, renames: Mapping[str, str],
           topic: str) -> np.ndarray:
    """Records of `dtype` from fixed-size CDR messages of type `msg` (message field `k` → record field
    `renames.get(k, k)`; record fields the message lacks are 0, message fields the record lacks ignored)."""
    out = np.zeros(len(messages), dtype=dtype)
    if not messages:
        return out
    sizes = {len(m) for m in messages}
    if sizes != {msg.dtype.itemsize}:
        raise McapFormatError(f"{topic}: message sizes {sorted(sizes)[:3]} bytes, expected {msg.dtype.itemsize}")
    arr = np.frombuffer(b"".join(messages), dtype=msg.dtype)
    if np.any(arr[HEADER_FIELD] & 0xFFFF != HEADER_WORD):
        raise McapFormatError(f"{topic}: message is not little-endian CDR")
    for f in msg.fields:
        target = renames.get(f.name, f.name)
        if target in (dtype.names or ()):
            out[target] = arr[f.name]
    return out
