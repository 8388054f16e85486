"""`BulkMessages`: many messages of one channel added to an mcap `Writer`'s open chunk at once.

`Writer.add_message` costs ~15 µs per message in Python (a Message object, six small writes and a seek per
record, statistics and index updates one by one): ~45 ms per 1000-period block with its ~2000 frames, more
than the rest of the logger. Here the records of a block are packed with one struct call each and written
with one `write`, the statistics and the chunk's message index are updated once per block, and message
indexes are written with numpy. The file is byte-identical to the one `add_message` writes (same records,
same chunk boundaries: a chunk is closed after the first message that takes it past the chunk size).

This reaches into the Writer's private state (mcap 1.x, `_Writer__…`); `BulkMessages.of` returns None when
that state is not there, and the caller then uses `add_message`.
"""

from __future__ import annotations

import bisect
import itertools
import struct
from collections.abc import Sequence
from typing import Any, Final

import numpy as np
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import MessageIndex
from mcap.writer import Writer

#: MCAP Message record header: opcode, record length (after these 9 bytes), channel id, sequence, log time,
#: publish time
_HEADER: Final = struct.Struct("<BQHIQQ")


class _MessageIndex(MessageIndex):
    """A chunk's message index written with numpy (mcap writes 2 small writes per entry)."""

    def write(self, stream: RecordBuilder) -> None:
        pairs = np.array(self.records, dtype="<u8").reshape(-1)
        stream.start_record(Opcode.MESSAGE_INDEX)
        stream.write2(self.channel_id)
        stream.write4(len(self.records) * 16)
        stream.write(pairs.tobytes())
        stream.finish_record()  # type: ignore[no-untyped-call]


class BulkMessages:
    """Adds blocks of messages to `writer` as repeated `add_message` calls would."""

    def __init__(self, writer: Writer) -> None:
        self._w: Any = writer
        self._chunk: Any = writer._Writer__chunk_builder  # type: ignore[attr-defined]
        self._stats: Any = writer._Writer__statistics  # type: ignore[attr-defined]
        self._limit = int(writer._Writer__chunk_size)  # type: ignore[attr-defined]
        self._finalize = writer._Writer__finalize_chunk  # type: ignore[attr-defined]
        if self._chunk is None:
            raise AttributeError("writer without chunks")

    @classmethod
    def of(cls, writer: Writer) -> BulkMessages | None:
        """A BulkMessages for `writer`, or None if this mcap version's Writer is not laid out as expected."""
        try:
            return cls(writer)
        except AttributeError:
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
            self._account(chunk, channel, times[i:j], list(zip(times[i:j], ends, strict=False)))
            if count > self._limit:
                self._finalize()
            i = j

    def _account(self, chunk: Any, channel: int, times: Sequence[int], index: list[tuple[int, int]]) -> None:
        """Statistics, chunk times and message index of messages just written (as `add_message` keeps them)."""
        k, t0, t1 = len(times), min(times), max(times)
        stats = self._stats
        stats.message_start_time = t0 if stats.message_count == 0 else min(t0, stats.message_start_time)
        stats.message_end_time = max(t1, stats.message_end_time)
        stats.channel_message_counts[channel] += k
        stats.message_count += k
        chunk.message_start_time = t0 if chunk.num_messages == 0 else min(t0, chunk.message_start_time)
        chunk.message_end_time = max(t1, chunk.message_end_time)
        entry = chunk.message_indices.get(channel)
        if not entry:
            entry = chunk.message_indices[channel] = _MessageIndex(channel_id=channel, records=[])
        entry.records.extend(index)
        chunk.num_messages += k
