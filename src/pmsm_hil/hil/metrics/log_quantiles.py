"""Quantiles of non-negative integer samples (e.g. lateness in ns) in fixed memory: counts in log-spaced buckets.

Values below 2^(SUB_BITS+1) (256 ns) have a bucket each (exact); above, every power of two [2^e, 2^(e+1)) is
split into 2^SUB_BITS (128) equal buckets of width 2^(e − SUB_BITS), so a bucket is at most 1/128 of its lower
bound wide and its midpoint — the value a sample is taken as — is within **1/256 (0.39 %)** of every sample in
it. Order statistics keep that bound (the map is monotone), so `percentile` and `median` are within 0.39 % of
numpy's linear-method figures for the same samples (exact below 256 ns); `maximum` and the sample count are
exact. The buckets cover every int64 (7 296 counters, 57 KiB), whatever the run's length: memory does not grow
with distinct values as `IntQuantiles` (quantiles.py) does. Negative samples count as 0.
"""

from __future__ import annotations

import math

import numpy as np

#: sub-buckets per power of two = 2^SUB_BITS (relative bucket width ≤ 2^-SUB_BITS)
SUB_BITS = 7
_SUB = 1 << SUB_BITS
_EXACT = 2 * _SUB  # values below this have their own bucket
_BUCKETS = _EXACT + (63 - (SUB_BITS + 1)) * _SUB
#: largest relative error of a quantile (half a bucket's relative width)
RELATIVE_ERROR = 1.0 / (2 * _SUB)


def bucket_index(values: np.ndarray) -> np.ndarray:
    """Bucket of each non-negative int64 value."""
    v = np.asarray(values, dtype=np.int64)
    out = v.copy()
    big = v >= _EXACT
    if big.any():
        vb = v[big]
        e = np.floor(np.log2(vb.astype(np.float64))).astype(np.int64)
        e -= (np.left_shift(np.int64(1), e) > vb).astype(np.int64)  # float rounding near powers of two
        e += (np.left_shift(np.int64(1), e + 1) <= vb).astype(np.int64)
        sub = np.right_shift(vb, e - SUB_BITS) - _SUB
        out[big] = _EXACT + (e - (SUB_BITS + 1)) * _SUB + sub
    return out


def bucket_bounds(index: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """[low, high) value bounds of each bucket (float64)."""
    i = np.asarray(index, dtype=np.int64)
    low = i.astype(np.float64)
    high = low + 1.0
    big = i >= _EXACT
    if big.any():
        k = i[big] - _EXACT
        e = k // _SUB + SUB_BITS + 1
        width = np.ldexp(1.0, (e - SUB_BITS).astype(np.int32))
        lo = (k % _SUB + _SUB) * width
        low[big], high[big] = lo, lo + width
    return low, high


class LogQuantiles:
    """Counts of non-negative integer samples in log-spaced buckets; quantiles of the samples times `scale`
    (e.g. 1e-3: ns → µs), within `RELATIVE_ERROR` of the exact figures. Same interface as `IntQuantiles`."""

    def __init__(self, scale: float = 1.0) -> None:
        self.scale = scale
        self._counts = np.zeros(_BUCKETS, dtype=np.int64)
        self._max = -1
        self.n = 0

    def add(self, values: np.ndarray) -> None:
        """Count a block of integer samples (negative ones as 0)."""
        v = np.asarray(values)
        if v.shape[0] == 0:
            return
        v = np.clip(v.astype(np.int64, copy=False), 0, None)
        self._counts += np.bincount(bucket_index(v), minlength=_BUCKETS)
        self._max = max(self._max, int(v.max()))
        self.n += int(v.shape[0])

    def _value_at(self, ends: np.ndarray, rank: int) -> float:
        """The representative of the sample of this rank (0-based, sorted): its bucket's midpoint (exact buckets:
        the value), clipped to the exact maximum."""
        b = int(np.searchsorted(ends, rank, side="right"))
        low, high = bucket_bounds(np.array([b]))
        mid = float(low[0]) if b < _EXACT else 0.5 * (float(low[0]) + float(high[0]))
        return min(mid, float(self._max)) * self.scale

    def percentile(self, q: float) -> float:
        """The q-th percentile (0–100), numpy's linear method on the bucket representatives; NaN without samples."""
        if self.n == 0:
            return math.nan
        ends = np.cumsum(self._counts)
        pos = min(max((self.n - 1) * (q / 100.0), 0.0), self.n - 1.0)
        lo = math.floor(pos)
        frac = pos - lo
        a = self._value_at(ends, lo)
        b = self._value_at(ends, min(lo + 1, self.n - 1))
        return a + (b - a) * frac

    def median(self) -> float:
        """The median; NaN without samples."""
        return self.percentile(50.0)

    def maximum(self) -> float:
        """The largest sample (exact); NaN without samples."""
        return float(self._max) * self.scale if self.n else math.nan


__all__ = ["RELATIVE_ERROR", "SUB_BITS", "LogQuantiles", "bucket_bounds", "bucket_index"]
