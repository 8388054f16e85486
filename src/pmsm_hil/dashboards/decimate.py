"""Min/max decimation of a time series for plotting: a bounded number of points, peaks kept."""

from __future__ import annotations

import numpy as np


def minmax_decimate(t: np.ndarray, y: np.ndarray, max_points: int) -> tuple[np.ndarray, np.ndarray]:
    """(t, y) reduced to at most `max_points` samples: the minimum and the maximum of each of
    `max_points // 2` equal buckets of samples, in time order (so every peak of `y` survives).

    Series of at most `max_points` samples are returned as they are. NaN samples are ignored within a
    bucket (an all-NaN bucket keeps one NaN: a gap in the plot). `max_points` must be ≥ 2."""
    if max_points < 2:
        raise ValueError(f"max_points: must be ≥ 2, got {max_points}")
    t, y = np.asarray(t, dtype=float), np.asarray(y, dtype=float)
    n = y.shape[0]
    if n <= max_points:
        return t, y
    buckets = max_points // 2
    size = -(-n // buckets)  # ceil: buckets · size ≥ n
    padded = np.full(buckets * size, np.nan)
    padded[:n] = y
    rows = padded.reshape(buckets, size)
    nan = np.isnan(rows)
    lo = np.argmin(np.where(nan, np.inf, rows), axis=1)
    hi = np.argmax(np.where(nan, -np.inf, rows), axis=1)
    base = np.arange(buckets) * size
    idx = np.unique(np.concatenate([base + lo, base + hi]))  # sorted: time order; lo == hi kept once
    idx = idx[idx < n]
    return t[idx], y[idx]
