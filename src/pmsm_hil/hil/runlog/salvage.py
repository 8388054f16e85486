"""`end_after_last_record`: turn an MCAP file whose writing failed (a full disk) into a valid MCAP file.

A write that fails part-way leaves a record cut at the end of the file. The file is truncated after its
last complete record (record headers only are read: no chunk is decompressed, so this is quick however large
the log) and ended with a Data End record, a Footer without a summary section and the closing magic: a
complete MCAP file any reader opens (a summary-less file is read linearly). Those ~50 bytes fit in the
space the truncation freed, unless the cut record was shorter than them.
"""

from __future__ import annotations

import errno
import io
import os
import struct
from dataclasses import dataclass
from pathlib import Path

from mcap.opcode import Opcode

MAGIC = b"\x89MCAP0\r\n"
_HEAD = struct.Struct("<BQ")
_INDEX = struct.Struct("<HI")  # Message Index body start: channel id, bytes of its (log_time, offset) entries
# Data End (data_section_crc 0: not computed) + Footer (summary_start 0: no summary; offsets 0; crc 0) + magic
_ENDING = (_HEAD.pack(Opcode.DATA_END, 4) + struct.pack("<I", 0)
           + _HEAD.pack(Opcode.FOOTER, 20) + struct.pack("<QQI", 0, 0, 0) + MAGIC)


@dataclass(frozen=True)
class Kept:
    """What a cut MCAP file keeps: bytes up to the end of its last complete record (0: not even the magic and
    the Header record), and messages of the counted channel in its complete chunks (from their Message Index
    records: nothing is decompressed)."""

    bytes: int
    messages: int


def last_record_end(path: Path, channel: int | None = None) -> Kept:
    """Where the last complete record of `path` ends, and how many messages of `channel` its complete chunks
    hold: from the Message Index records of every chunk but the last, and by reading the last chunk itself (a
    write that failed right after it may have cut its Message Index records, which would count its messages
    as none)."""
    messages = after_last_chunk = 0
    last_chunk: tuple[int, int] | None = None  # (body offset, length) of the last complete Chunk record
    with open(path, "rb") as f:
        size = f.seek(0, os.SEEK_END)
        f.seek(0)
        if f.read(len(MAGIC)) != MAGIC:
            return Kept(0, 0)
        pos = len(MAGIC)
        while pos + _HEAD.size <= size:
            f.seek(pos)
            opcode, length = _HEAD.unpack(f.read(_HEAD.size))
            end = pos + _HEAD.size + length
            if end > size or opcode in (Opcode.DATA_END, Opcode.FOOTER):
                break
            if opcode == Opcode.CHUNK:
                last_chunk, after_last_chunk = (pos + _HEAD.size, length), 0
            elif opcode == Opcode.MESSAGE_INDEX and channel is not None and length >= _INDEX.size:
                index_channel, entries_bytes = _INDEX.unpack(f.read(_INDEX.size))
                if index_channel == channel:
                    messages += entries_bytes // 16  # (log_time, offset) per message
                    after_last_chunk += entries_bytes // 16
            pos = end
        if channel is not None and last_chunk is not None:
            f.seek(last_chunk[0])
            in_chunk = _messages_in_chunk(f.read(last_chunk[1]), channel)
            if in_chunk is not None:
                messages += in_chunk - after_last_chunk
    return Kept(pos, messages) if pos > len(MAGIC) else Kept(0, 0)


def _messages_in_chunk(body: bytes, channel: int) -> int | None:
    """Messages of `channel` in a Chunk record's `body` (decompressed, CRC checked); None if it cannot be read."""
    from mcap.data_stream import ReadDataStream
    from mcap.exceptions import McapError
    from mcap.records import Chunk, Message
    from mcap.stream_reader import breakup_chunk

    try:
        chunk = Chunk.read(ReadDataStream(io.BytesIO(body)))
        return sum(1 for r in breakup_chunk(chunk, validate_crc=True)
                   if isinstance(r, Message) and r.channel_id == channel)
    except (McapError, ValueError, struct.error, RuntimeError):
        return None


def end_after_last_record(path: Path, channel: int | None = None) -> Kept:
    """Truncate `path` after its last complete record and end it as a valid MCAP file; returns what it keeps
    (`Kept.bytes` 0: nothing could be kept, the file is then left as it was, for the caller to remove).
    OSError if the file cannot be opened or the ending not written (the file is then left truncated after its
    last complete record, which `hil mcap-repair` and `hil.runlog.reader` read)."""
    path = Path(path)
    kept = last_record_end(path, channel)
    if kept.bytes == 0:
        return kept
    fd = os.open(path, os.O_WRONLY)
    try:
        os.ftruncate(fd, kept.bytes)
        if os.pwrite(fd, _ENDING, kept.bytes) != len(_ENDING):
            raise OSError(errno.ENOSPC, "no space left for the MCAP ending")
        os.fsync(fd)
    except OSError:
        os.ftruncate(fd, kept.bytes)
        raise
    finally:
        os.close(fd)
    return kept
