"""Message encoders/decoders of the run log (the fixed-size CDR `/periods` and `/frames` are in `cdr.py`).

`/link_faults` is JSON (JSON-schema channel), built with a %-format template per block, the fields constant
over the block written into it once; logs written before the CDR change have `/periods` and `/frames` in
JSON too (`decode_json_records`, `decode_frames_json` read them). Non-finite floats are written as `null`
(JSON has no NaN) and read back as NaN.
`/trace` blocks are ROS 2 CDR (schema encoding `ros2msg`, one `float64[]` per field): formatting
50 000 floats as JSON text costs ≈ 130 ms per 1000-period block, far too slow; CDR is a memcpy and
Foxglove decodes it natively.
"""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Callable, Sequence
from typing import Any, Final

import numpy as np

from pmsm_hil.hil.records import FAULT_DTYPE, FRAME_DTYPE, TRACE_DTYPE
from pmsm_hil.hil.runlog import layouts
from pmsm_hil.hil.runlog.errors import McapFormatError

CDR_LE_HEADER: Final = b"\x00\x01\x00\x00"
UNITS: Final = layouts.UNITS
METADATA_JSON_SCHEMA: Final = layouts.METADATA_JSON_SCHEMA


def json_schema(dtype: np.dtype, title: str) -> bytes:
    """JSON schema (draft 7) describing one record of the structured `dtype` as a JSON object (`layouts.json_schema`
    of its fields)."""
    fields = []
    for name in dtype.names or ():
        field = dtype[name]
        fields.append(layouts.Field(name, f"{field.base.kind}{field.base.itemsize}",
                                    int(np.prod(field.shape)) if field.shape else 0))
    return layouts.json_schema(fields, title)


def _template(dtype: np.dtype, names: Sequence[str]) -> str:
    parts = []
    for name in names:
        shape = dtype[name].shape
        if shape:
            parts.append(f'"{name}":[' + ",".join(["%s"] * shape[0]) + "]")
        else:
            parts.append(f'"{name}":%s')
    return "{" + ",".join(parts) + "}"


def _split_columns(block: np.ndarray, names: Sequence[str]) -> list[np.ndarray]:
    """Columns of `block` in template order (sub-array fields split per element), as numpy views."""
    cols: list[np.ndarray] = []
    for name in names:
        arr = block[name]
        cols.extend([arr[:, k] for k in range(arr.shape[1])] if arr.ndim == 2 else [arr])
    return cols


def _constant_text(col: np.ndarray) -> str | None:
    """The JSON text of every value of `col` if they are all the same (all NaN included), else None."""
    first = col[0]
    if col.dtype.kind == "f" and not math.isfinite(float(first)):
        same = bool(np.all(np.isnan(col))) if math.isnan(float(first)) else bool(np.all(col == first))
        return "null" if same else None
    return str(first.item()) if bool(np.all(col == first)) else None


def make_json_encoder(dtype: np.dtype) -> Callable[[np.ndarray], list[bytes]]:
    """Return a function encoding each record of a `dtype` block as one compact JSON object (bytes).

    Per block, the fields whose value is the same in every record (a fixed load, the unused second set of a
    three-phase run, ...) are written into the template once, so only the others are formatted per record."""
    names = list(dtype.names or ())
    slots = _template(dtype, names).split("%s")  # text before each value, and after the last

    def encode(block: np.ndarray) -> list[bytes]:
        if block.shape[0] == 0:
            return []
        parts, varying = [slots[0]], []
        for col, after in zip(_split_columns(block, names), slots[1:], strict=True):
            text = _constant_text(col)
            if text is None:
                values = col.tolist()
                if col.dtype.kind == "f":
                    for i in np.flatnonzero(~np.isfinite(col)).tolist():
                        values[i] = "null"
                varying.append(values)
                parts.append("%s")
            else:
                parts.append(text)
            parts.append(after)
        template = "".join(parts)
        if not varying:
            return [template.encode()] * block.shape[0]
        return [(template % row).encode() for row in zip(*varying, strict=True)]

    return encode


encode_faults: Final = make_json_encoder(FAULT_DTYPE)


def ros2msg_schema(dtype: np.dtype) -> bytes:
    """ROS 2 .msg text of a trace block: one `float64[]` per field of `dtype` (all fields float64)."""
    return layouts.ros2msg_schema(dtype.names or ())


def ros2msg_fields(schema: bytes) -> tuple[str, ...]:
    """Field names of a trace schema written by `ros2msg_schema` (McapFormatError if it is not one)."""
    names: list[str] = []
    for line in schema.decode("utf-8", errors="replace").splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        kind, _, name = line.partition(" ")
        if kind != "float64[]" or not name.strip().isidentifier():
            raise McapFormatError(f"/trace: schema line {line!r} is not 'float64[] NAME'")
        names.append(name.strip())
    if not names:
        raise McapFormatError("/trace: schema has no fields")
    return tuple(names)


def encode_trace_cdr(block: np.ndarray) -> bytes:
    """CDR (little endian) of a trace block (any all-float64 trace dtype, fields in order): per field uint32
    count, 4 pad bytes, float64 data."""
    n = block.shape[0]
    prefix = struct.pack("<II", n, 0)
    parts = [CDR_LE_HEADER]
    for name in block.dtype.names or ():
        parts.append(prefix)
        parts.append(np.ascontiguousarray(block[name], dtype="<f8").tobytes())
    return b"".join(parts)


def decode_trace_cdr(data: bytes, dtype: np.dtype = TRACE_DTYPE) -> np.ndarray:
    """Inverse of `encode_trace_cdr` for a block of `dtype`; raises McapFormatError on a malformed message."""
    if data[:4] != CDR_LE_HEADER:
        raise McapFormatError("/trace: message is not little-endian CDR")
    pos = 4
    cols: dict[str, np.ndarray] = {}
    for name in dtype.names or ():
        if pos + 4 > len(data):
            raise McapFormatError(f"/trace: message truncated before field {name}")
        (count,) = struct.unpack_from("<I", data, pos)
        pos += 4
        pos += (-(pos - 4)) % 8
        end = pos + 8 * count
        if end > len(data):
            raise McapFormatError(f"/trace: field {name} needs {8 * count} bytes, message too short")
        cols[name] = np.frombuffer(data, dtype="<f8", count=count, offset=pos)
        pos = end
    lengths = {c.shape[0] for c in cols.values()}
    if len(lengths) != 1:
        raise McapFormatError("/trace: fields have different lengths")
    out = np.empty(lengths.pop(), dtype=dtype)
    for name, col in cols.items():
        out[name] = col
    return out


def _as_float(value: Any) -> float:
    return math.nan if value is None else float(value)


#: Period fields added after the first logs were written: absent in older files, read as 0.
LATE_FIELDS: Final = frozenset({"narrow_pulses_gated", "mirror", "n_duties", "duties"})


def decode_json_records(messages: Sequence[bytes], dtype: np.dtype, field: str) -> np.ndarray:
    """Decode JSON objects written by `make_json_encoder(dtype)` back into a `dtype` array (null → NaN;
    a `LATE_FIELDS` field missing from an older log → 0)."""
    out = np.zeros(len(messages), dtype=dtype)
    if not messages:
        return out
    try:
        rows = [json.loads(m) for m in messages]
        for name in dtype.names or ():
            if name in LATE_FIELDS and name not in rows[0]:
                continue
            values = [row[name] for row in rows]
            if dtype[name].base.kind == "f":
                if dtype[name].shape:
                    out[name] = [[_as_float(v) for v in vals] for vals in values]
                else:
                    out[name] = [_as_float(v) for v in values]
            else:
                out[name] = values
    except (ValueError, KeyError, TypeError) as exc:
        raise McapFormatError(f"{field}: cannot decode JSON message ({exc})") from None
    return out


def decode_frames_json(messages: Sequence[bytes], field: str) -> np.ndarray:
    """FRAME_DTYPE array of JSON frame messages (JSON-era logs: t, seq, dir, id, fd, len, data as hex; the
    payload padded with zeros, `length` = payload bytes, null t → NaN)."""
    out = np.zeros(len(messages), dtype=FRAME_DTYPE)
    try:
        for i, m in enumerate(messages):
            d = json.loads(m)
            payload = bytes.fromhex(d["data"])
            out[i] = (_as_float(d["t"]), d["seq"], d["dir"], d["id"], bool(d["fd"]), len(payload),
                      np.frombuffer(payload.ljust(FRAME_DTYPE["data"].shape[0], b"\0"), dtype=np.uint8))
    except (ValueError, KeyError, TypeError) as exc:
        raise McapFormatError(f"{field}: cannot decode message ({exc})") from None
    return out


def periods_log_times_ns(block: np.ndarray) -> np.ndarray:
    """log_time [ns] (uint64) of each record: its `t` (s), non-finite or negative times clamped to 0."""
    t = np.nan_to_num(np.asarray(block["t"], dtype=np.float64), nan=0.0, posinf=0.0, neginf=0.0)
    ns: np.ndarray = np.rint(np.clip(t, 0.0, 9.0e9) * 1e9).astype(np.uint64)
    return ns
