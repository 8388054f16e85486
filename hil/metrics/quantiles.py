"""Exact quantiles of integer samples (e.g. execution times in ns) from counts, in memory bounded by the
number of distinct values instead of the number of samples.

`median` and `percentile` return what numpy's `np.median` / `np.percentile` (linear method) return for
the same samples scaled by `scale`, without holding them.
"""

from __future__ import annotations

import math

import numpy as np


class IntQuantiles:
    """Counts of integer samples; quantiles of the samples times `scale` (e.g. 1e-3: ns → µs)."""

    def __init__(self, scale: float = 1.0) -> None:
        self.scale = scale
        self._counts: dict[int, int] = {}
        self.n = 0

    def add(self, values: np.ndarray) -> None:
        """Count a block of integer samples."""
        if values.shape[0] == 0:
            return
        uniq, cnt = np.unique(np.asarray(values, dtype=np.int64), return_counts=True)
        counts = self._counts
        for v, c in zip(uniq.tolist(), cnt.tolist(), strict=True):
            counts[v] = counts.get(v, 0) + c
        self.n += int(values.shape[0])

    def _sorted(self) -> tuple[np.ndarray, np.ndarray]:
        keys = np.fromiter(sorted(self._counts), dtype=np.int64, count=len(self._counts))
        ends = np.cumsum([self._counts[int(k)] for k in keys], dtype=np.int64)
        return keys, ends  # sample i (0-based, sorted) is keys[searchsorted(ends, i, 'right')]

    def _at(self, keys: np.ndarray, ends: np.ndarray, i: int) -> float:
        return float(np.float64(keys[int(np.searchsorted(ends, i, side="right"))]) * self.scale)

    def percentile(self, q: float) -> float:
        """The q-th percentile (0–100), numpy's linear method; NaN without samples."""
        if self.n == 0:
            return math.nan
        keys, ends = self._sorted()
        pos = min(max((self.n - 1) * (q / 100.0), 0.0), self.n - 1.0)  # numpy's virtual index
        lo = math.floor(pos)
        frac = pos - lo
        a = self._at(keys, ends, lo)
        b = self._at(keys, ends, min(lo + 1, self.n - 1))
        diff = b - a
        return b - diff * (1.0 - frac) if frac >= 0.5 else a + diff * frac  # numpy's _lerp

    def median(self) -> float:
        """The median (mean of the two middle samples for an even count); NaN without samples."""
        if self.n == 0:
            return math.nan
        keys, ends = self._sorted()
        half = self.n // 2
        if self.n % 2:
            return self._at(keys, ends, half)
        return (self._at(keys, ends, half - 1) + self._at(keys, ends, half)) / 2.0

    def maximum(self) -> float:
        """The largest sample; NaN without samples."""
        return float(np.float64(max(self._counts)) * self.scale) if self._counts else math.nan
