"""`BulkMessages`: many messages of one channel added to an mcap `Writer`'s open chunk at once.

`Writer.add_message` costs ~15 µs per message in Python (a Message object, six small writes and a seek per
record, statistics and index updates one by one): ~45 ms per 1000-period block with its ~2000 frames, more
than the rest of the logger. Here the records of a block are packed with one struct call each and written
with one `write`, the statistics and the chunk's message index are updated once per block, and message
indexes are written with numpy. The file is byte-identical to the one `add_message` writes (same records,
same chunk boundaries: a chunk is closed after the first message that takes it past the chunk size).

Fixed-size messages (`/periods`, `/frames`: CDR, one size per topic) go through `add_packed` (the block's
Message records as bytes, from `pure_writer.FixedMessages`) or `add_records` (as one numpy structured array:
`message_records`, header fields and payload at their byte offsets), each written with one `write` per chunk.
A chunk's message index is kept as packed (log time, offset) pairs, written in one piece. numpy is imported by
the numpy calls only (`message_records`, `add_records`): the logger process starts without it.

The Writer's private state (its open chunk, statistics, chunk size) is reached through
`mcap_writer_internals`, the one module that reads it; `BulkMessages.of` returns None when the installed mcap
lacks it, and the caller then uses `add_message`.
"""

from __future__ import annotations

import bisect
import itertools
import sys
from array import array
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Final

from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import MessageIndex
from mcap.writer import Writer

from pmsm_hil.hil.runlog.mcap_writer_internals import McapLayoutError, writer_internals
from pmsm_hil.hil.runlog.pure_writer import MESSAGE_HEADER as _HEADER

if TYPE_CHECKING:
    import numpy as np

_HEADER_FIELDS: Final = (("opcode", "u1", 0), ("length", "<u8", 1), ("channel", "<u2", 9), ("sequence", "<u4", 11),
                         ("log_time", "<u8", 15), ("publish_time", "<u8", 23))


def message_records(payload: np.dtype, n: int) -> np.ndarray:
    """`n` zeroed MCAP Message records with a fixed-size `payload` (a structured dtype): fields opcode,
    length, channel, sequence, log_time, publish_time [ns] and `data` (the payload, at byte 31)."""
    import numpy as np

    names = [f[0] for f in _HEADER_FIELDS] + ["data"]
    formats = [f[1] for f in _HEADER_FIELDS] + [payload]
    offsets = [f[2] for f in _HEADER_FIELDS] + [_HEADER.size]
    dtype = np.dtype({"names": names, "formats": formats, "offsets": offsets,
                      "itemsize": _HEADER.size + payload.itemsize})
    return np.zeros(n, dtype=dtype)


def index_pairs(times: Sequence[int], offsets: Sequence[int]) -> bytes:
    """Message index entries: (log time [ns], offset in the chunk) per message, little-endian uint64 pairs."""
    pairs = array("Q", bytes(16 * len(times)))
    pairs[0::2] = array("Q", times)
    pairs[1::2] = array("Q", offsets)
    if sys.byteorder != "little":
        pairs.byteswap()
    return pairs.tobytes()


class _MessageIndex(MessageIndex):
    """A chunk's message index kept as packed (log time, offset) pairs (`index_pairs`), written in one piece
    (mcap writes 2 small writes per entry)."""

    def __init__(self, channel_id: int, parts: list[bytes]) -> None:
        super().__init__(channel_id=channel_id, records=[])
        self.parts = parts

    def write(self, stream: RecordBuilder) -> None:
        pairs = b"".join(self.parts)
        stream.start_record(Opcode.MESSAGE_INDEX)
        stream.write2(self.channel_id)
        stream.write4(len(pairs))
        stream.write(pairs)
        stream.finish_record()  # type: ignore[no-untyped-call]


class BulkMessages:
    """Adds blocks of messages to `writer` as repeated `add_message` calls would."""

    def __init__(self, writer: Writer) -> None:
        state = writer_internals(writer)
        self._chunk: Any = state.chunk
        self._stats: Any = state.statistics
        self._limit = state.chunk_size
        self._finalize = state.finalize_chunk

    @classmethod
    def of(cls, writer: Writer) -> BulkMessages | None:
        """A BulkMessages for `writer`, or None if this mcap version's Writer is not laid out as expected (or
        does not chunk)."""
        try:
            return cls(writer)
        except McapLayoutError:
            return None

    def add(self, channel: int, times: Sequence[int], msgs: Sequence[bytes], seqs: Sequence[int]) -> None:
        """Messages `msgs` on `channel`, log and publish time `times` [ns], sequence numbers `seqs`."""
        n, i, pack, head = len(msgs), 0, _HEADER.pack, _HEADER.size
        sizes = [head + len(m) for m in msgs]
        chunk = self._chunk
        while i < n:
            start = chunk.count
            ends = list(itertools.accumulate(sizes[i:], initial=start))  # chunk size before each message
            # up to and including the message that takes the chunk past its size
            j = i + min(bisect.bisect_right(ends, self._limit, lo=1), n - i)
            headers = [pack(Opcode.MESSAGE, size - 9, channel, seq, t, t)
                       for size, seq, t in zip(sizes[i:j], seqs[i:j], times[i:j], strict=True)]
            chunk.record_writer.write(b"".join(itertools.chain.from_iterable(zip(headers, msgs[i:j], strict=True))))
            count = ends[j - i]
            if chunk.count != count:
                raise RuntimeError(f"mcap chunk: {chunk.count - start} bytes written, {count - start} expected")
            part = times[i:j]
            self._account(chunk, channel, len(part), min(part), max(part), index_pairs(part, ends[: j - i]))
            if count > self._limit:
                self._finalize()
            i = j

    def add_packed(self, channel: int, records: bytes | bytearray, size: int, times: Sequence[int]) -> None:
        """Message records of `size` bytes each (on `channel`, opcode, length and channel set, log times `times`
        [ns]) written as they are."""
        n, i, chunk, view = len(times), 0, self._chunk, memoryview(records)
        if len(records) != n * size:
            raise RuntimeError(f"mcap messages: {len(records)} bytes for {n} records of {size}")
        while i < n:
            start = chunk.count
            # up to and including the message that takes the chunk past its size
            j = i + min(max(1, (self._limit - start) // size + 1), n - i)
            chunk.record_writer.write(view[i * size : j * size])
            if chunk.count != start + (j - i) * size:
                raise RuntimeError(f"mcap chunk: {chunk.count - start} bytes written, {(j - i) * size} expected")
            part = times[i:j]
            self._account(chunk, channel, j - i, min(part), max(part),
                          index_pairs(part, range(start, start + (j - i) * size, size)))
            if chunk.count > self._limit:
                self._finalize()
            i = j

    def add_records(self, channel: int, records: np.ndarray) -> None:
        """Messages of `records` (from `message_records`, sequence, times and data set) on `channel`; sets
        their opcode, length and channel."""
        import numpy as np

        size, n, i, chunk = records.dtype.itemsize, records.shape[0], 0, self._chunk
        records["opcode"] = Opcode.MESSAGE
        records["length"] = size - 9
        records["channel"] = channel
        raw = records.view(np.uint8) if records.flags.c_contiguous else np.ascontiguousarray(records).view(np.uint8)
        while i < n:
            start = chunk.count
            # up to and including the message that takes the chunk past its size
            j = i + min(max(1, (self._limit - start) // size + 1), n - i)
            chunk.record_writer.write(raw[i * size : j * size].data)
            if chunk.count != start + (j - i) * size:
                raise RuntimeError(f"mcap chunk: {chunk.count - start} bytes written, {(j - i) * size} expected")
            offsets = start + size * np.arange(j - i, dtype=np.uint64)
            times = records["log_time"][i:j]
            pairs = np.column_stack((times, offsets)).astype("<u8", copy=False).tobytes()
            self._account(chunk, channel, j - i, int(times.min()), int(times.max()), pairs)
            if chunk.count > self._limit:
                self._finalize()
            i = j

    def _account(self, chunk: Any, channel: int, k: int, t0: int, t1: int, pairs: bytes) -> None:
        """Statistics, chunk times and message index of `k` messages just written (as `add_message` keeps them):
        log times `t0`..`t1` [ns], `pairs` their index entries (`index_pairs`)."""
        stats = self._stats
        stats.message_start_time = t0 if stats.message_count == 0 else min(t0, stats.message_start_time)
        stats.message_end_time = max(t1, stats.message_end_time)
        stats.channel_message_counts[channel] += k
        stats.message_count += k
        chunk.message_start_time = t0 if chunk.num_messages == 0 else min(t0, chunk.message_start_time)
        chunk.message_end_time = max(t1, chunk.message_end_time)
        entry = chunk.message_indices.get(channel)
        if not isinstance(entry, _MessageIndex):  # none yet, or mcap's own (messages added by add_message)
            parts = [index_pairs([t for t, _ in entry.records], [o for _, o in entry.records])] if entry else []
            entry = chunk.message_indices[channel] = _MessageIndex(channel, parts)
        entry.parts.append(pairs)
        chunk.num_messages += k
