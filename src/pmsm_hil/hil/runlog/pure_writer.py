"""The logger's numpy-free encoders: a block of packed records → its MCAP Message records, a trace block → its CDR.

`FixedMessages` turns a PERIOD or FRAME record block (the ring's bytes) into the Message records `BulkMessages`
writes: one `struct` unpack and one pack per record (the record's fields copied as a few byte runs, the CDR
padding zero), then a byte table applied to each field that is not a plain copy (a frame's `fd` as 0/1, its `len`
clamped to the data field). `trace_message` is a trace block's CDR through a strided `memoryview`. The bytes are
those of the numpy encoders (`cdr.fill_periods`, `cdr.fill_frames`, `encoding.encode_trace_cdr`,
`encoding.periods_log_times_ns`); `tests/runlog/test_pure_writer.py` compares the files. A little-endian host
only (the ring holds native records): `LITTLE_ENDIAN` False sends every write to the numpy encoders.
"""

from __future__ import annotations

import math
import struct
import sys
from collections.abc import Mapping, Sequence
from typing import Final

from mcap.opcode import Opcode

from pmsm_hil.hil.runlog import layouts
from pmsm_hil.hil.runlog.errors import RunLogError

LITTLE_ENDIAN: Final = sys.byteorder == "little"
#: MCAP Message record header: opcode, record length (after these 9 bytes), channel id, sequence, log time,
#: publish time [ns]
MESSAGE_HEADER: Final = struct.Struct("<BQHIQQ")
CDR_LE_HEADER: Final = b"\x00\x01\x00\x00"
_LOG_TIME_MAX_S: Final = 9.0e9


def log_time_ns(t: float) -> int:
    """log_time [ns] of a record at `t` [s]: non-finite or negative times 0, at most 9e9 s, rounded half to even
    (as `encoding.periods_log_times_ns`)."""
    if not t > 0.0 or t == math.inf:  # NaN, ≤ 0, +inf
        return 0
    return round(min(t, _LOG_TIME_MAX_S) * 1e9)


#: byte tables of the fields that are not copied as they are
AS_BOOL: Final = bytes([0] + [1] * 255)
CLAMP_FRAME_LENGTH: Final = bytes(min(i, layouts.FRAME_DATA_BYTES) for i in range(256))


class FixedMessages:
    """Encodes blocks of packed `fields` records as MCAP Message records of the fixed-size CDR message `msg`
    (message field `k` ← record field `renames.get(k, k)`, same size; `tables[k]`: a 256-byte table the field's
    byte goes through). The records start with `t` (float64, s) and `seq` (uint32): log time and sequence."""

    def __init__(self, fields: Sequence[layouts.Field], msg: layouts.CdrLayout,
                 renames: Mapping[str, str] | None = None, tables: Mapping[str, bytes] | None = None) -> None:
        renames, tables = dict(renames or {}), dict(tables or {})
        if [f[:2] for f in fields[:2]] != [("t", "f8"), ("seq", "u4")]:
            raise RunLogError("records must start with t (f8) and seq (u4)")
        src_at = layouts.offsets(fields)
        src_size = {f.name: layouts.field_bytes(f) for f in fields}
        self.record_bytes = layouts.record_size(fields)
        self.size = MESSAGE_HEADER.size + msg.size  # one Message record [bytes]
        runs: list[list[int]] = []  # [record offset, message offset, bytes], contiguous on both sides
        self._tables: list[tuple[int, bytes]] = []
        for slot in msg.slots:
            name = renames.get(slot.name, slot.name)
            if src_size[name] != slot.size:
                raise RunLogError(f"{slot.name}: {slot.size} bytes in the message, {src_size[name]} in the record")
            table = tables.get(slot.name, AS_BOOL if slot.ros_type == "bool" else None)
            if table is not None:
                self._tables.append((MESSAGE_HEADER.size + slot.offset, table))
            last = runs[-1] if runs else None
            if last is not None and last[0] + last[2] == src_at[name] and last[1] + last[2] == slot.offset:
                last[2] += slot.size
            else:
                runs.append([src_at[name], slot.offset, slot.size])
        src, out, src_pos, out_pos = ["<"], ["<BQHIQQ4s"], 0, 4
        for rec_at, msg_at, n in runs:
            if rec_at < src_pos:
                raise RunLogError("message fields must be in record order")
            src.append(f"{rec_at - src_pos}x{n}s" if rec_at > src_pos else f"{n}s")
            out.append(f"{msg_at - out_pos}x{n}s" if msg_at > out_pos else f"{n}s")
            src_pos, out_pos = rec_at + n, msg_at + n
        src.append(f"{self.record_bytes - src_pos}x" if self.record_bytes > src_pos else "")
        out.append(f"{msg.size - out_pos}x" if msg.size > out_pos else "")
        self._runs = struct.Struct("".join(src))
        self._out = struct.Struct("".join(out))
        self._t_seq = struct.Struct(f"<dI{self.record_bytes - 12}x")
        if self._out.size != self.size:
            raise RunLogError(f"message record of {self._out.size} bytes, expected {self.size}")

    def encode(self, raw: bytes, channel: int) -> tuple[bytes | bytearray, list[int]]:
        """The Message records on `channel` of the records in `raw` (concatenated, `size` bytes each) and their
        log times [ns]."""
        t_seq = list(self._t_seq.iter_unpack(raw))
        times = [log_time_ns(t) for t, _ in t_seq]
        pack, length = self._out.pack, self.size - 9
        body = b"".join([pack(Opcode.MESSAGE, length, channel, seq, ns, ns, CDR_LE_HEADER, *runs)
                         for runs, (_, seq), ns in zip(self._runs.iter_unpack(raw), t_seq, times, strict=True)])
        if not self._tables:
            return body, times
        out = bytearray(body)
        view = memoryview(out)
        for at, table in self._tables:
            view[at :: self.size] = view[at :: self.size].tobytes().translate(table)
        return out, times


PERIODS: Final = FixedMessages(layouts.PERIOD_FIELDS, layouts.PERIOD_MSG)
FRAMES: Final = FixedMessages(layouts.FRAME_FIELDS, layouts.FRAME_MSG, layouts.FRAME_RENAMES,
                              {"len": CLAMP_FRAME_LENGTH})


def trace_message(raw: bytes, n_fields: int) -> tuple[int, bytes, int]:
    """The log time [ns] (its first sample's), the CDR message and the sample count of the trace block `raw`
    (`n_fields` float64 per sample): per field uint32 count, 4 pad bytes, the field's values."""
    doubles = memoryview(raw).cast("d")
    n = len(doubles) // n_fields
    prefix = struct.pack("<II", n, 0)
    parts = [CDR_LE_HEADER]
    for k in range(n_fields):
        parts.append(prefix)
        parts.append(doubles[k::n_fields].tobytes())
    return (log_time_ns(doubles[0]) if n else 0), b"".join(parts), n
