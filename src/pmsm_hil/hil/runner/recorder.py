"""Per-period records packed straight into PERIOD_DTYPE / FRAME_DTYPE bytes (cheap in the loop)."""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from pmsm_hil.hil.errors import HilError
from pmsm_hil.hil.records import FRAME_DTYPE, PERIOD_DTYPE
from pmsm_hil.protocol.frame import Frame

#: struct layout identical to PERIOD_DTYPE (numpy packs unaligned by default).
PERIOD_STRUCT: Final = struct.Struct("<dI11dB3B3IBBI3I3H2BHB5dB6d")
#: struct layout identical to FRAME_DTYPE.
FRAME_STRUCT: Final = struct.Struct("<dIBIBB64s")

if PERIOD_STRUCT.size != PERIOD_DTYPE.itemsize or FRAME_STRUCT.size != FRAME_DTYPE.itemsize:
    raise ImportError("recorder struct layouts are out of step with src/pmsm_hil/hil/records.py dtypes")


class RecordsNotKeptError(HilError):
    """The records of a long run were streamed to the log and the metrics, not kept in memory."""


class ByteRecords:
    """Packed records in a buffer; `take()` returns the new block as a structured array.

    `reserve(n)` pre-allocates (and touches) room for n records so a paced loop never waits on a
    reallocation or a page fault; `append_packed` then writes in place. With `keep=False` a `take()` also
    drops the records it returns (the buffer is reused: memory stays at one block), and `all()` then
    refuses with `RecordsNotKeptError`.
    """

    def __init__(self, dtype: np.dtype, fmt: struct.Struct, *, keep: bool = True) -> None:
        self.dtype = dtype
        self.pack = fmt.pack
        self.pack_into = fmt.pack_into
        self.size = fmt.size
        self.buf = bytearray()
        self.end = 0  # bytes in use
        self._taken = 0
        self.keep = keep
        #: records dropped after a `take()` (keep=False)
        self.dropped = 0

    def reserve(self, records: int) -> None:
        """Make room for `records` more records without reallocating."""
        need = self.end + records * self.size
        if need > len(self.buf):
            self.buf.extend(bytes(need - len(self.buf)))

    def append_packed(self, packed: bytes | memoryview) -> None:
        """Append records already packed with the matching struct (any bytes-like object)."""
        end = self.end + len(packed)
        if end > len(self.buf):
            self.buf.extend(bytes(max(end - len(self.buf), 1 << 16)))
        self.buf[self.end:end] = packed
        self.end = end

    def __len__(self) -> int:
        return self.end // self.dtype.itemsize

    def take(self) -> npt.NDArray[np.void]:
        """Records appended since the last take (a copy)."""
        start = self._taken
        block = np.frombuffer(bytes(memoryview(self.buf)[start:self.end]), dtype=self.dtype)  # one memcpy
        if self.keep:
            self._taken = self.end
        else:
            self.dropped += block.shape[0]
            self.end = self._taken = 0
        return block

    def all(self) -> npt.NDArray[np.void]:
        """Every record so far (a copy); `RecordsNotKeptError` if some were dropped (keep=False)."""
        if self.dropped:
            raise RecordsNotKeptError(
                f"records: {self.dropped} records of this run were streamed to the log and the metrics, not "
                f"kept in memory (runs of more than {KEEP_PERIODS_MAX} periods); read them from its run.mcap")
        return np.frombuffer(bytes(memoryview(self.buf)[: self.end]), dtype=self.dtype)


#: period records of runs up to this many periods stay in memory (`LoopOutcome.periods.all()`, ≈ 37 MB);
#: longer runs stream them (to the logger and the metrics) in blocks
KEEP_PERIODS_MAX = 200_000


def period_records(*, keep: bool = True) -> ByteRecords:
    """Empty period record store."""
    return ByteRecords(PERIOD_DTYPE, PERIOD_STRUCT, keep=keep)


def frame_records(*, keep: bool = True) -> ByteRecords:
    """Empty raw-frame record store."""
    return ByteRecords(FRAME_DTYPE, FRAME_STRUCT, keep=keep)


class FrameTap:
    """Wraps the host's link and records every frame sent and received (no re-encoding).

    The loop sets `t` [s] and `seq` (period index) each period; records use FRAME_DTYPE layout.
    """

    def __init__(self, link: Any, records: ByteRecords) -> None:
        self.link = link
        self.stats = link.stats
        self.fd: bool = bool(getattr(link, "fd", False))
        self.records = records
        self.t = 0.0
        self.seq = 0
        self._pack = records.pack
        self._append = records.append_packed

    def send(self, frames: Sequence[Frame]) -> None:
        """Record then send frames host → target."""
        for fr in frames:
            self._append(self._pack(self.t, self.seq, 0, fr.arbitration_id, fr.is_fd, len(fr.data), fr.data))
        self.link.send(frames)

    def poll(self) -> Frame | None:
        """Poll one frame target → host and record it."""
        fr: Frame | None = self.link.poll()
        if fr is not None:
            self._append(self._pack(self.t, self.seq, 1, fr.arbitration_id, fr.is_fd, len(fr.data), fr.data))
        return fr

    def recv(self, timeout_s: float) -> Frame | None:
        """Blocking receive with recording."""
        fr: Frame | None = self.link.recv(timeout_s)
        if fr is not None:
            self._append(self._pack(self.t, self.seq, 1, fr.arbitration_id, fr.is_fd, len(fr.data), fr.data))
        return fr

    def close(self) -> None:
        """Close the wrapped link."""
        self.link.close()
