"""Tolerant MCAP reading: scan the valid prefix record by record (whole chunks only) and decode topics.

A file cut by a kill has no summary/footer and may end inside a chunk; the scanner stops at the first
incomplete or corrupt record (chunk CRCs are checked), so everything up to the last complete chunk is
recovered. Complete files are read the same way.
"""

from __future__ import annotations

import io
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Channel, Chunk, McapRecord, Message, Metadata, Schema
from mcap.stream_reader import breakup_chunk
from mcap.well_known import MessageEncoding

from pmsm_hil.hil.records import FAULT_DTYPE, FRAME_DTYPE, PERIOD_DTYPE, TRACE_DTYPE, trace_dtype
from pmsm_hil.hil.runlog import cdr, encoding, topics
from pmsm_hil.hil.runlog.errors import McapFormatError

MAGIC = b"\x89MCAP0\r\n"
_HEAD = struct.Struct("<BQ")


@dataclass
class ScanState:
    """What a scan found: bytes of valid prefix, whether the data section ended properly, chunks read."""

    file_bytes: int = 0
    valid_bytes: int = 0
    complete: bool = False
    chunks: int = 0
    stop_reason: str = ""
    skipped_opcodes: dict[int, int] = field(default_factory=dict)
    #: topics of the channels seen (filled by `read_topic`)
    topics: set[str] = field(default_factory=set)

    def cut_reason(self, path: Path, use: str) -> str:
        """Why a scan of `path` that did not end properly is refused, and the way out (`hil mcap-repair`), for a
        command that would `use` the file (replay, export)."""
        return (f"cut or corrupt after {self.valid_bytes} of {self.file_bytes} bytes ({self.stop_reason}); "
                f"`hil mcap-repair {path}` writes its valid prefix as a complete file to {use}")


def _parse(opcode: int, body: bytes) -> McapRecord | None:
    stream = ReadDataStream(io.BytesIO(body))
    record: McapRecord | None = None
    if opcode == Opcode.SCHEMA:
        record = Schema.read(stream)
    elif opcode == Opcode.CHANNEL:
        record = Channel.read(stream)
    elif opcode == Opcode.MESSAGE:
        record = Message.read(stream, len(body))
    elif opcode == Opcode.METADATA:
        record = Metadata.read(stream)
    elif opcode == Opcode.CHUNK:
        record = Chunk.read(stream)
    return record


def scan_records(path: Path, state: ScanState) -> Iterator[McapRecord]:
    """Yield the Schema, Channel, Message and Metadata records of the valid prefix of `path`.

    Updates `state` as it goes; raises McapFormatError if `path` is not an MCAP file."""
    try:
        f = open(path, "rb")  # noqa: SIM115 - closed in finally (generator)
    except OSError as exc:
        raise McapFormatError(f"path: cannot open {path} ({exc})") from None
    try:
        f.seek(0, io.SEEK_END)
        state.file_bytes = f.tell()
        f.seek(0)
        if f.read(len(MAGIC)) != MAGIC:
            raise McapFormatError(f"path: {path} is not an MCAP file (bad magic)")
        state.valid_bytes = len(MAGIC)
        while True:
            head = f.read(_HEAD.size)
            if len(head) < _HEAD.size:
                state.stop_reason = "end of file" if not head else "cut inside a record header"
                return
            opcode, length = _HEAD.unpack(head)
            if length > state.file_bytes - f.tell():
                state.stop_reason = f"cut inside a record (opcode 0x{opcode:02x})"
                return
            body = f.read(length)
            if opcode == Opcode.DATA_END:
                state.valid_bytes = f.tell()
                state.complete = True
                state.stop_reason = "data end"
                return
            try:
                record = _parse(opcode, body)
                inner = breakup_chunk(record, validate_crc=True) if isinstance(record, Chunk) else None
            except (McapError, ValueError, struct.error, RuntimeError) as exc:
                state.stop_reason = f"corrupt record (opcode 0x{opcode:02x}): {exc}"
                return
            if inner is not None:
                state.chunks += 1
                yield from inner
            elif record is not None:
                yield record
            else:
                state.skipped_opcodes[opcode] = state.skipped_opcodes.get(opcode, 0) + 1
            state.valid_bytes = f.tell()
    finally:
        f.close()


@dataclass
class TopicMessages:
    """The messages of one topic in file order, with the message encoding and schema of its channel(s)."""

    messages: list[Message]
    message_encoding: str = ""
    schema: bytes | None = None


def read_topic(path: Path, topic: str, state: ScanState | None = None) -> TopicMessages:
    """All messages of `topic` in the valid prefix of `path` (McapFormatError if its channels disagree on
    the message encoding or schema); `state`, if given, receives what the scan found (complete or cut, the
    topics of all channels)."""
    schemas: dict[int, bytes] = {}
    channels: dict[int, tuple[str, bytes | None]] = {}
    out = TopicMessages([])
    state = ScanState() if state is None else state
    for record in scan_records(Path(path), state):
        if isinstance(record, Schema):
            schemas[record.id] = record.data
        elif isinstance(record, Channel):
            state.topics.add(record.topic)
            if record.topic != topic:
                continue
            channels[record.id] = (record.message_encoding, schemas.get(record.schema_id))
            if len(set(channels.values())) > 1:
                raise McapFormatError(f"{topic}: channels with different encodings or schemas")
            out.message_encoding, out.schema = channels[record.id]
        elif isinstance(record, Message) and record.channel_id in channels:
            out.messages.append(record)
    return out


def read_topic_messages(path: Path, topic: str) -> list[Message]:
    """All messages of `topic` in the valid prefix of `path`, in file order."""
    return read_topic(path, topic).messages


def _read_fixed(path: Path, topic: str, dtype: np.dtype, renames: dict[str, str],
                state: ScanState | None = None) -> TopicMessages | np.ndarray:
    """`dtype` records of a CDR `topic` (decoded with the file's own schema), or its messages if the topic is
    not CDR (a JSON-era log)."""
    found = read_topic(path, topic, state)
    if found.message_encoding != MessageEncoding.CDR:
        return found
    if found.schema is None:
        raise McapFormatError(f"{topic}: channel without its schema")
    data = [m.data for m in found.messages]
    msg = cdr.parse_schema(found.schema, topic, len(data[0]) if data else None)
    out: np.ndarray = cdr.decode(data, msg, dtype, renames, topic)
    return out


def read_periods(path: Path, state: ScanState | None = None) -> np.ndarray:
    """PERIOD_DTYPE array of all /periods messages (CDR, or JSON in older logs: null → NaN; truncated files:
    the valid prefix); `state` as for `read_topic`."""
    found = _read_fixed(path, topics.TOPIC_PERIODS, PERIOD_DTYPE, {}, state)
    if isinstance(found, np.ndarray):
        return found
    out: np.ndarray = encoding.decode_json_records([m.data for m in found.messages], PERIOD_DTYPE,
                                                   topics.TOPIC_PERIODS)
    return out


def read_faults(path: Path) -> np.ndarray:
    """FAULT_DTYPE array of all /link_faults messages (kind: index into FAULT_KINDS)."""
    msgs = read_topic_messages(path, topics.TOPIC_FAULTS)
    out: np.ndarray = encoding.decode_json_records([m.data for m in msgs], FAULT_DTYPE, topics.TOPIC_FAULTS)
    return out


def read_frames(path: Path, state: ScanState | None = None) -> np.ndarray:
    """FRAME_DTYPE array of all /frames messages (CDR, or JSON with a hex payload in older logs: padded with
    zeros); `state` as for `read_topic`."""
    found = _read_fixed(path, topics.TOPIC_FRAMES, FRAME_DTYPE, cdr.FRAME_RENAMES, state)
    if isinstance(found, np.ndarray):
        return found
    return encoding.decode_frames_json([m.data for m in found.messages], topics.TOPIC_FRAMES)


def read_trace(path: Path) -> np.ndarray:
    """All /trace blocks concatenated, in the layout the file's trace schema names (TRACE_DTYPE for a
    three-phase run, TRACE_DTYPE6 for a dual three-phase one; TRACE_DTYPE if the file has no trace)."""
    found = read_topic(path, topics.TOPIC_TRACE)
    dtype = TRACE_DTYPE
    if found.message_encoding:
        if found.schema is None:
            raise McapFormatError(f"{topics.TOPIC_TRACE}: channel without its schema")
        dtype = trace_dtype(encoding.ros2msg_fields(found.schema))
    blocks = [encoding.decode_trace_cdr(m.data, dtype) for m in found.messages]
    out: np.ndarray = np.concatenate(blocks) if blocks else np.zeros(0, dtype=dtype)
    return out


def read_metadata(path: Path) -> dict[str, str]:
    """The run metadata record (empty if absent)."""
    for record in scan_records(Path(path), ScanState()):
        if isinstance(record, Metadata) and record.name == topics.TOPIC_METADATA:
            return dict(record.metadata)
    return {}
