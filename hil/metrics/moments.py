"""Time-weighted mean, variance, minimum and maximum of a sampled signal, accumulated block by block.

Each sample is weighted by its share of the time axis (trapezoidal weights): an interval [t_i, t_i+1]
gives half its length to each end. Blocks are joined exactly: the last sample of a block is carried into
the next, so every interval is counted once, and the blocks' statistics are merged with the parallel
(Chan) update. One block gives the same figures as the whole-array formulas of `torque.py`; many blocks
agree with them to rounding (~1e-15 relative), with memory independent of the signal's length.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def interval_weights(t: np.ndarray) -> np.ndarray:
    """Unnormalised trapezoidal weights [s] of samples at times `t` (s): half of each adjacent interval."""
    n = t.shape[0]
    w = np.zeros(n, dtype=np.float64)
    if n < 2:
        return w
    dt = np.diff(t)
    w[0] = dt[0] / 2.0
    w[-1] = dt[-1] / 2.0
    w[1:-1] = (dt[:-1] + dt[1:]) / 2.0
    return w


@dataclass(slots=True)
class _Block:
    weight: float  # Σw [s]
    mean: float
    var: float  # Σw(x − mean)² / Σw


class WeightedMoments:
    """Streaming time-weighted mean/variance (and min/max) of one signal; `add(t, x)` per block."""

    def __init__(self) -> None:
        self._total: _Block | None = None
        self._carry: tuple[float, float] | None = None  # (t, x) of the last sample seen
        self.minimum = math.inf
        self.maximum = -math.inf
        self.samples = 0

    def add(self, t: np.ndarray, x: np.ndarray) -> None:
        """Add samples `x` at strictly increasing times `t` [s] (after those already added)."""
        if t.shape[0] == 0:
            return
        xs = np.ascontiguousarray(x, dtype=np.float64)
        self.samples += xs.shape[0]
        self.minimum = min(self.minimum, float(xs.min()))
        self.maximum = max(self.maximum, float(xs.max()))
        if self._carry is not None:
            t = np.concatenate(([self._carry[0]], t))
            xs = np.concatenate(([self._carry[1]], xs))
        self._carry = (float(t[-1]), float(xs[-1]))
        w = interval_weights(np.asarray(t, dtype=np.float64))
        total = float(w.sum())
        if total <= 0.0:
            return
        wn = w / total
        mean = float(np.sum(wn * xs))  # not np.dot: BLAS threads stall for ms on a loaded machine
        self._merge(_Block(total, mean, float(np.sum(wn * (xs - mean) ** 2))))

    def _merge(self, b: _Block) -> None:
        a = self._total
        if a is None:
            self._total = b
            return
        weight = a.weight + b.weight
        fa, fb = a.weight / weight, b.weight / weight
        delta = b.mean - a.mean
        self._total = _Block(weight, a.mean + delta * fb, fa * a.var + fb * b.var + delta * delta * fa * fb)

    @property
    def mean(self) -> float:
        """Time-weighted mean (the only sample's value when a single sample was added; NaN if none)."""
        if self._total is not None:
            return self._total.mean
        return self._carry[1] if self._carry is not None else math.nan

    @property
    def rms_deviation(self) -> float:
        """sqrt of the time-weighted mean squared deviation from `mean` (0 for a single sample)."""
        return math.sqrt(self._total.var) if self._total is not None else 0.0
