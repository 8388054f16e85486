"""The last `span_s` seconds of a high-rate trace, kept block by block (memory bounded by the span)."""

from __future__ import annotations

from collections import deque

import numpy as np


class TraceTail:
    """Keeps the trace records whose time is within `span_s` [s] of the newest one."""

    def __init__(self, dtype: np.dtype, span_s: float) -> None:
        self.dtype = dtype
        self.span_s = span_s
        self._blocks: deque[np.ndarray] = deque()

    def add(self, block: np.ndarray) -> None:
        """Append a block (a copy is kept) and drop whole blocks that ended before the span."""
        if block.shape[0] == 0:
            return
        self._blocks.append(np.array(block, copy=True))
        start = float(block["t"][-1]) - self.span_s
        while len(self._blocks) > 1 and float(self._blocks[1]["t"][0]) <= start:
            self._blocks.popleft()

    def array(self) -> np.ndarray:
        """The records of the last `span_s` seconds (all of them when the trace is shorter)."""
        if not self._blocks:
            return np.zeros(0, dtype=self.dtype)
        rows = self._blocks[0] if len(self._blocks) == 1 else np.concatenate(list(self._blocks))
        start = float(rows["t"][-1]) - self.span_s
        if float(rows["t"][0]) >= start:
            return rows
        return rows[int(np.searchsorted(rows["t"], start, side="left")):]
