"""Exact quantiles of integer samples (e.g. execution times in ns) from counts, in memory bounded by the
number of distinct values instead of the number of samples.

`median` and `percentile` return what numpy's `np.median` / `np.percentile` (linear method) return for
the same samples scaled by `scale`, without holding them.
"""

from __future__ import annotations

import math

import numpy as np

#: samples collected before they are counted (one np.unique per this many, not per block)
PENDING = 1 << 16


class IntQuantiles:
    """Counts of integer samples; quantiles of the samples times `scale` (e.g. 1e-3: ns → µs).

    A block is copied into a pending buffer; every `PENDING` samples (and before a query) they are counted
    and merged into the sorted distinct values and their counts, all in numpy."""

    def __init__(self, scale: float = 1.0) -> None:
        self.scale = scale
        self._keys = np.zeros(0, dtype=np.int64)  # distinct values, sorted
        self._counts = np.zeros(0, dtype=np.int64)  # how often each
        self._pending = np.empty(0, dtype=np.int64)
        self._n_pending = 0
        self.n = 0

    def add(self, values: np.ndarray) -> None:
        """Count a block of integer samples."""
        m = values.shape[0]
        if m == 0:
            return
        if self._n_pending + m > PENDING:
            self._fold()
        if m > PENDING:
            self._merge(np.asarray(values, dtype=np.int64))
        else:
            if self._pending.shape[0] == 0:
                self._pending = np.empty(PENDING, dtype=np.int64)
            np.copyto(self._pending[self._n_pending : self._n_pending + m], values, casting="unsafe")
            self._n_pending += m
        self.n += int(m)

    def _fold(self) -> None:
        """Count the pending samples."""
        if self._n_pending:
            self._merge(self._pending[: self._n_pending])
            self._n_pending = 0

    def _merge(self, values: np.ndarray) -> None:
        uniq, cnt = np.unique(values, return_counts=True)
        keys, counts = self._keys, self._counts
        at = np.searchsorted(keys, uniq)
        known = at < keys.shape[0]
        known[known] = keys[at[known]] == uniq[known]
        counts[at[known]] += cnt[known]
        new = ~known
        if new.any():
            self._keys = np.insert(keys, at[new], uniq[new])
            self._counts = np.insert(counts, at[new], cnt[new])

    def _sorted(self) -> tuple[np.ndarray, np.ndarray]:
        self._fold()
        return self._keys, np.cumsum(self._counts)  # sample i (0-based, sorted) is keys[searchsorted(ends, i, 'right')]

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
        self._fold()
        return float(np.float64(self._keys[-1]) * self.scale) if self._keys.shape[0] else math.nan

    def histogram(self, edges: np.ndarray) -> np.ndarray:
        """Counts of the samples in the bins [edges[i], edges[i+1]) of raw (unscaled) integer values; samples below
        edges[0] count in the first bin, from edges[-1] on in the last (len(edges) - 1 bins)."""
        self._fold()
        bins = np.searchsorted(edges, self._keys, side="right") - 1
        bins = np.clip(bins, 0, edges.shape[0] - 2)
        return np.bincount(bins, weights=self._counts, minlength=edges.shape[0] - 1).astype(np.int64)
