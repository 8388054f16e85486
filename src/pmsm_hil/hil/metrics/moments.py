"""Time-weighted mean, variance, minimum and maximum of a sampled signal, accumulated block by block.

Each sample is weighted by its share of the time axis (trapezoidal weights): an interval [t_i, t_i+1]
gives half its length to each end. Blocks are joined exactly: the last sample of a block is carried into
the next (it gets the half of the junction interval), so every interval is counted once, and the blocks'
statistics are merged with the parallel (Chan) update. One block gives the same figures as the whole-array
formulas of `torque.py`; many blocks agree with them to rounding (~1e-15 relative), with memory independent
of the signal's length.

Per block the work is a few contiguous numpy passes into reused buffers (no allocation once warm): the
weights are computed once per block of times (`TrapezoidWeights`) and shared by every signal sampled at
those times (`WeightedMoments.add_weighted`). The weights are kept doubled (sums of adjacent intervals):
scaling by 2 is exact, so the figures equal those of the halved weights.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def buffer_room(buf: np.ndarray, n: int) -> np.ndarray:
    """`buf` if it holds ≥ n float64, else a new buffer of max(n, 1.25·len) (grows rarely)."""
    return buf if buf.shape[0] >= n else np.empty(max(n, buf.shape[0] + buf.shape[0] // 4), dtype=np.float64)


class TrapezoidWeights:
    """Doubled trapezoidal weights [s] of consecutive blocks of sample times, joined across blocks.

    After `add(t)`: `w2[i]` = t[i+1] − t[i−1] for the block's samples (the last one gets only its left
    interval, the first one also the junction interval from the previous block's last time), `carry2` = the
    junction interval (twice the previous block's last sample's share; 0 for the first block) and `total2` =
    carry2 + Σw2 (twice the time the block's weights cover).
    """

    def __init__(self) -> None:
        self.t_last: float | None = None
        self.carry2 = 0.0
        self.total2 = 0.0
        self.w2 = np.empty(0, dtype=np.float64)
        self._buf = np.empty(0, dtype=np.float64)

    def add(self, t: np.ndarray, dt: np.ndarray | None = None) -> None:
        """Weights of the block of strictly increasing times `t` [s] (after those already added); `dt`:
        np.diff(t) if the caller has it already."""
        n = t.shape[0]
        if n == 0:
            self.w2, self.carry2, self.total2 = self._buf[:0], 0.0, 0.0
            return
        self._buf = buffer_room(self._buf, n)
        w2 = self._buf[:n]
        if dt is None:
            dt = np.diff(t)
        t0, t1 = float(t[0]), float(t[-1])
        junction = t0 - self.t_last if self.t_last is not None else 0.0
        if n == 1:
            w2[0] = junction
        else:
            np.add(dt[:-1], dt[1:], out=w2[1:-1])
            w2[0] = junction + float(dt[0])
            w2[-1] = float(dt[-1])
        self.w2, self.carry2, self.t_last = w2, junction, t1
        self.total2 = junction + float(np.sum(w2))


@dataclass(slots=True)
class _Block:
    weight: float  # Σw [s]
    mean: float
    var: float  # Σw(x − mean)² / Σw


class WeightedMoments:
    """Streaming time-weighted mean/variance (and min/max) of one signal; `add(t, x)` per block, or
    `add_weighted(x, weights)` with the weights of its times shared by several signals."""

    def __init__(self) -> None:
        self._total: _Block | None = None
        self._carry: float | None = None  # x of the last sample seen
        self._weights: TrapezoidWeights | None = None  # own weights, for `add`
        self._buf = np.empty(0, dtype=np.float64)
        self._dev = np.empty(0, dtype=np.float64)
        self.minimum = math.inf
        self.maximum = -math.inf
        self.samples = 0

    def add(self, t: np.ndarray, x: np.ndarray) -> None:
        """Add samples `x` at strictly increasing times `t` [s] (after those already added)."""
        if t.shape[0] == 0:
            return
        if self._weights is None:
            self._weights = TrapezoidWeights()
        self._weights.add(np.ascontiguousarray(t, dtype=np.float64))
        self.add_weighted(np.ascontiguousarray(x, dtype=np.float64), self._weights)

    def add_weighted(self, x: np.ndarray, weights: TrapezoidWeights) -> None:
        """Add the samples `x` (contiguous float64) at the times of `weights`' last block (`weights.add`
        called for this block; the same weights serve every signal sampled at those times)."""
        n = x.shape[0]
        if n == 0:
            return
        self.samples += n
        self.minimum = min(self.minimum, float(x.min()))
        self.maximum = max(self.maximum, float(x.max()))
        carry, self._carry = self._carry, float(x[-1])
        total2 = weights.total2
        if total2 <= 0.0:
            return
        self._buf = buf = buffer_room(self._buf, n)
        self._dev = dev = buffer_room(self._dev, n)
        prod, y = buf[:n], dev[:n]
        w2, c2 = weights.w2, weights.carry2
        np.multiply(w2, x, out=prod)
        mean = (float(np.sum(prod)) + (c2 * carry if carry is not None else 0.0)) / total2
        np.subtract(x, mean, out=y)
        np.multiply(w2, y, out=prod)
        np.multiply(prod, y, out=prod)
        s2 = float(np.sum(prod))
        if carry is not None:
            s2 += c2 * (carry - mean) ** 2
        self._merge(_Block(total2 / 2.0, mean, s2 / total2))

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
        return self._carry if self._carry is not None else math.nan

    @property
    def rms_deviation(self) -> float:
        """sqrt of the time-weighted mean squared deviation from `mean` (0 for a single sample)."""
        return math.sqrt(self._total.var) if self._total is not None else 0.0
