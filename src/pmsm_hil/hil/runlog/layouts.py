"""The record and message layouts the logger process writes, as plain tuples (no numpy).

`PERIOD_FIELDS`, `FRAME_FIELDS`, `FAULT_FIELDS` and `TRACE_FIELDS` are `pmsm_hil.hil.records`' PERIOD_DTYPE,
FRAME_DTYPE, FAULT_DTYPE and TRACE_DTYPE field by field (packed, native little endian);
`tests/runlog/test_pure_writer.py` checks they stay equal. `cdr_message` lays a fixed-size ROS 2 CDR message out
as `cdr.message_type` does (same offsets, same schema text), `json_schema` writes the JSON schema
`encoding.json_schema` writes. The logger process needs nothing else to open a run log: numpy (≈ 0.2 CPU-s to
import) is loaded only when a write needs it (docs/logging.md, "The logger process").
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any, Final, NamedTuple


class Field(NamedTuple):
    """One field of a record: name, type code (`f8`, `u4`, `u2`, `u1`) and fixed array `length` (0: a scalar)."""

    name: str
    code: str
    length: int = 0


#: bytes of each type code
SIZES: Final = {"f8": 8, "u4": 4, "u2": 2, "u1": 1}
#: the ROS 2 primitive of each type code
ROS_TYPES: Final = {"f8": "float64", "u4": "uint32", "u2": "uint16", "u1": "uint8"}
#: bytes of each ROS 2 primitive a fixed-size message of the run log uses
ROS_SIZES: Final = {"float64": 8, "uint32": 4, "uint16": 2, "uint8": 1, "bool": 1}

PERIOD_FIELDS: Final = (
    Field("t", "f8"), Field("seq", "u4"), Field("i_a", "f8"), Field("i_b", "f8"), Field("i_c", "f8"),
    Field("i_d", "f8"), Field("i_q", "f8"), Field("torque", "f8"), Field("omega_m", "f8"), Field("theta_e", "f8"),
    Field("torque_ref", "f8"), Field("speed_ref", "f8"), Field("load_torque", "f8"), Field("n_states", "u1"),
    Field("states", "u1", 3), Field("durations_ns", "u4", 3), Field("vector_id", "u1"), Field("candidates", "u1"),
    Field("exec_time_ns", "u4"), Field("exec_split_ns", "u4", 3), Field("leg_transitions", "u2"),
    Field("boundary_transitions", "u2"), Field("narrow_pulses", "u2"), Field("late", "u1"), Field("missed", "u1"),
    Field("narrow_pulses_gated", "u2"), Field("mirror", "u1"), Field("i_u", "f8"), Field("i_v", "f8"),
    Field("i_w", "f8"), Field("i_x", "f8"), Field("i_y", "f8"), Field("n_duties", "u1"), Field("duties", "f8", 6),
)
FRAME_DATA_BYTES: Final = 64
FRAME_FIELDS: Final = (
    Field("t", "f8"), Field("seq", "u4"), Field("direction", "u1"), Field("arbitration_id", "u4"),
    Field("is_fd", "u1"), Field("length", "u1"), Field("data", "u1", FRAME_DATA_BYTES),
)
FAULT_FIELDS: Final = (Field("t", "f8"), Field("seq", "u4"), Field("direction", "u1"), Field("kind", "u1"),
                       Field("arbitration_id", "u4"))
#: the default trace's fields (all float64)
TRACE_FIELDS: Final = ("t", "i_a", "i_b", "i_c", "torque", "omega_m")

UNITS: Final = {
    "t": "s (sim time, period start)",
    "i_a": "A",
    "i_b": "A",
    "i_c": "A",
    "i_d": "A",
    "i_q": "A",
    "i_u": "A (second three-phase set)",
    "i_v": "A (second three-phase set)",
    "i_w": "A (second three-phase set)",
    "i_x": "A (x-y harmonic subspace)",
    "i_y": "A (x-y harmonic subspace)",
    "torque": "N·m",
    "torque_ref": "N·m",
    "load_torque": "N·m",
    "omega_m": "rad/s (mechanical)",
    "speed_ref": "rad/s (mechanical)",
    "theta_e": "rad (electrical)",
    "durations_ns": "ns",
    "exec_time_ns": "ns",
    "exec_split_ns": "ns (measure, reference, predict)",
    "states": "switching state codes 4·Sa+2·Sb+Sc (first n_states valid)",
    "duties": "duty 0..1 per leg of a duty-cycle Command (first n_duties valid, NaN beyond)",
}


def field_bytes(field: Field) -> int:
    """Bytes of `field` in a record."""
    return SIZES[field.code] * max(field.length, 1)


def offsets(fields: Sequence[Field]) -> dict[str, int]:
    """Byte offset of each field in a packed record of `fields`."""
    out, pos = {}, 0
    for f in fields:
        out[f.name] = pos
        pos += field_bytes(f)
    return out


def record_size(fields: Sequence[Field]) -> int:
    """Bytes of one packed record of `fields`."""
    return sum(field_bytes(f) for f in fields)


class MsgSlot(NamedTuple):
    """One field of a fixed-size CDR message: name, ROS 2 primitive, fixed array `length` (0: a scalar), byte
    offset in the message (the 4-byte encapsulation header included) and size [bytes]."""

    name: str
    ros_type: str
    length: int
    offset: int
    size: int


class CdrLayout(NamedTuple):
    """A fixed-size CDR message: its fields at their offsets, its size [bytes] and its ros2msg schema text."""

    slots: tuple[MsgSlot, ...]
    size: int
    schema: bytes


def cdr_message(fields: Sequence[tuple[str, str, int]], title: str, notes: Mapping[str, str] = UNITS) -> CdrLayout:
    """The layout of a message of `fields` ((name, ROS 2 primitive, count) each): a 4-byte header, then each
    primitive aligned to its size relative to the end of the header; the schema has `title` as a comment and
    `notes[name]` as each field's comment."""
    slots, pos, lines = [], 0, [f"# {title}"]
    for name, ros_type, count in fields:
        size = ROS_SIZES[ros_type]
        pos += -pos % size
        slots.append(MsgSlot(name, ros_type, count, 4 + pos, size * max(count, 1)))
        pos += size * max(count, 1)
        note = f"  # {notes[name]}" if name in notes else ""
        lines.append(f"{ros_type}{f'[{count}]' if count else ''} {name}{note}")
    return CdrLayout(tuple(slots), 4 + pos, ("\n".join(lines) + "\n").encode())


PERIOD_MSG: Final = cdr_message([(f.name, ROS_TYPES[f.code], f.length) for f in PERIOD_FIELDS],
                                "pmsm_hil control period (PERIOD_DTYPE), SI units")
#: frame message field → FRAME_FIELDS field, where the names differ
FRAME_RENAMES: Final = {"dir": "direction", "id": "arbitration_id", "fd": "is_fd", "len": "length"}
FRAME_MSG: Final = cdr_message(
    (("t", "float64", 0), ("seq", "uint32", 0), ("dir", "uint8", 0), ("id", "uint32", 0), ("fd", "bool", 0),
     ("len", "uint8", 0), ("data", "uint8", FRAME_DATA_BYTES)),
    "pmsm_hil raw link frame (FRAME_DTYPE)",
    {"t": "s (sim time)", "dir": "0 host→target, 1 target→host", "id": "arbitration id",
     "fd": "CAN FD", "len": f"payload bytes: the first len of data count (≤ {FRAME_DATA_BYTES})"},
)


def json_schema(fields: Sequence[Field], title: str) -> bytes:
    """JSON schema (draft 7) describing one record of `fields` as a JSON object."""
    props: dict[str, Any] = {}
    for f in fields:
        base: dict[str, Any] = {"type": ["number", "null"] if f.code[0] == "f" else "integer"}
        if f.name in UNITS:
            base["description"] = UNITS[f.name]
        if f.length:
            props[f.name] = {
                "type": "array",
                "items": {"type": base["type"]},
                **({"description": base["description"]} if "description" in base else {}),
            }
        else:
            props[f.name] = base
    schema = {
        "$schema": "http://json-schema.org/draft-07/schema#",
        "title": title,
        "type": "object",
        "properties": props,
    }
    return json.dumps(schema).encode()


METADATA_JSON_SCHEMA: Final = json.dumps(
    {
        "$schema": "http://json-schema.org/draft-07/schema#",
        "title": "pmsm_hil run metadata",
        "type": "object",
        "additionalProperties": {"type": "string"},
    }
).encode()

CONSOLE_JSON_SCHEMA: Final = json.dumps({
    "$schema": "http://json-schema.org/draft-07/schema#",
    "title": "target console line",
    "type": "object",
    "properties": {"t": {"type": "number", "description": "s (wall time since the target process started)"},
                   "seq": {"type": "integer"}, "stream": {"type": "string"}, "text": {"type": "string"}},
}).encode()

BOARD_JSON_SCHEMA: Final = json.dumps({
    "$schema": "http://json-schema.org/draft-07/schema#",
    "title": "virtual board period",
    "type": "object",
    "properties": {"period": {"type": "integer"}, "t": {"type": "number", "description": "s (period start)"},
                   "isr_us": {"type": "number", "description": "µs in interrupt handlers"},
                   "isr_entries": {"type": "integer", "description": "exception entries"},
                   "cpu_load": {"type": "number", "description": "share of cycles not asleep"},
                   "late_compares": {"type": "integer", "description": "1: compare values a period late"}},
}).encode()


def ros2msg_schema(names: Sequence[str]) -> bytes:
    """ROS 2 .msg text of a trace block: one `float64[]` per field (all fields float64)."""
    lines = ["# Plant trace block, SI units (t s, currents A, torque N·m, omega_m rad/s mechanical)"]
    lines += [f"float64[] {name}" for name in names]
    return ("\n".join(lines) + "\n").encode()
