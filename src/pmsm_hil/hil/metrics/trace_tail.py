"""The last `span_s` seconds of a high-rate trace, kept block by block in a reused ring buffer.

Memory is bounded by the span plus one block (the ring is sized from the trace's sample rate when it first
has to grow, and only grows again if the rate rises); once warm, a block costs one copy into memory that is
already mapped (no allocation, no page faults).
"""

from __future__ import annotations

import math

import numpy as np


class TraceTail:
    """Keeps the trace records whose time is within `span_s` [s] of the newest one."""

    def __init__(self, dtype: np.dtype, span_s: float) -> None:
        self.dtype = dtype
        self.span_s = span_s
        self._ring = np.empty(0, dtype=dtype)
        self._head = 0  # ring index of the oldest kept record
        self._n = 0  # records kept
        self._t_last = -math.inf

    @property
    def capacity(self) -> int:
        """Records the ring can hold."""
        return int(self._ring.shape[0])

    def add(self, block: np.ndarray) -> None:
        """Copy a block in (times after those already added) and forget the records older than the span."""
        n = block.shape[0]
        if n == 0:
            return
        if block.dtype != self.dtype:
            block = self._convert(block)
        t = block["t"]
        t_last = float(t[-1])
        start = t_last - self.span_s
        if float(t[0]) <= start:  # the block alone covers the span
            self._head = self._n = 0
            block = block[int(np.searchsorted(t, start, side="left")):]
            n = block.shape[0]
        else:
            self._drop_before(start)
        if self._n + n > self.capacity:
            self._grow(self._n + n, block)
        cap = self.capacity
        pos = (self._head + self._n) % cap
        first = min(n, cap - pos)
        ring, rows = _bytes(self._ring), _bytes(block)
        ring[pos : pos + first] = rows[:first]
        if first < n:
            ring[: n - first] = rows[first:]
        self._n += n
        self._t_last = t_last

    def array(self) -> np.ndarray:
        """The records of the last `span_s` seconds (all of them when the trace is shorter), a copy."""
        self._drop_before(self._t_last - self.span_s)
        out = np.empty(self._n, dtype=self.dtype)
        self._copy_kept(_bytes(out))
        return out

    def _drop_before(self, start: float) -> None:
        """Forget the kept records with t < start [s] (they are the oldest)."""
        if self._n == 0:
            return
        cap = self.capacity
        end = self._head + self._n
        older = self._ring["t"][self._head : min(end, cap)]
        drop = int(np.searchsorted(older, start, side="left"))
        if drop == older.shape[0] and end > cap:
            drop += int(np.searchsorted(self._ring["t"][: end - cap], start, side="left"))
        self._head = (self._head + drop) % cap
        self._n -= drop

    def _grow(self, need: int, block: np.ndarray) -> None:
        """A larger ring (the kept records moved to its start): room for the span at the sample rate of
        `block` plus two blocks, at least `need` records."""
        n = block.shape[0]
        size = need
        duration = float(block["t"][-1]) - float(block["t"][0])
        if duration > 0.0 and math.isfinite(self.span_s * (n - 1) / duration):
            size = max(need, math.ceil(self.span_s * (n - 1) / duration * 1.02) + 2 * n)  # span at the rate
        ring = np.empty(size, dtype=self.dtype)
        self._copy_kept(_bytes(ring))
        self._ring, self._head = ring, 0

    def _copy_kept(self, out: np.ndarray) -> None:
        """Copy the kept records, oldest first, to the start of `out` (rows of bytes, as `_bytes`)."""
        ring, cap, end = _bytes(self._ring), self.capacity, self._head + self._n
        if end <= cap:
            out[: self._n] = ring[self._head : end]
        else:
            k = cap - self._head
            out[:k] = ring[self._head :]
            out[k : self._n] = ring[: end - cap]

    def _convert(self, block: np.ndarray) -> np.ndarray:
        """`block`'s fields of `dtype`, by name, as a `dtype` array."""
        out = np.empty(block.shape[0], dtype=self.dtype)
        for name in self.dtype.names or ():
            out[name] = block[name]
        return out


def _bytes(records: np.ndarray) -> np.ndarray:
    """Records as rows of bytes (n, itemsize): numpy copies those with memcpy, structured records field by
    field (~20 times slower)."""
    return np.ascontiguousarray(records).view(np.uint8).reshape(records.shape[0], records.dtype.itemsize)
