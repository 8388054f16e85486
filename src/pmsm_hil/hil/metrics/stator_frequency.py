"""The stator electrical frequency measured from the phase currents, and whether it held still over the span.

The harmonic metrics (fundamental, THD) need the frequency the stator currents really run at: p·ω_m for a
synchronous machine, p·ω_m + ω_slip for an induction machine. It is measured, not assumed: the currents of one
three-phase set go through the Clarke transform (i_α = (2/3)(i_a − (i_b + i_c)/2), i_β = (i_b − i_c)/√3), are
averaged over `SMOOTH_S` (100 µs: switching ripple out, the fundamental kept for f1 up to ~1 kHz), and the angle
of the space vector i_α + j·i_β is unwrapped; f1 = |Δangle|/(2π·Δt) between the angles at the span's ends, each
the mean over one electrical period (harmonics of f1 average out; a span shorter than two electrical periods:
|slope|/2π of the angle's least-squares line).

Stationarity: f1 over each of `SEGMENTS` equal parts of the span (from the angle averaged over one electrical
period at the parts' ends, so harmonics average out); `change_pct` = 100·(max − min)/f1 (a span shorter than two
electrical periods is not judged). A span whose fundamental changes by more than `MAX_CHANGE_PCT` (a speed step, an
acceleration) has no single fundamental: the harmonic metrics are then not applicable.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: averaging interval before the angle is taken [s]
SMOOTH_S = 100e-6
#: parts of the span whose frequencies are compared
SEGMENTS = 4
#: largest change of the fundamental over the span for the harmonic metrics to apply [% of f1]
MAX_CHANGE_PCT = 2.0
#: below this space-vector amplitude [A] (mean over the span) the angle is noise: no frequency
MIN_AMPLITUDE_A = 1e-6


@dataclass(frozen=True, slots=True)
class StatorFrequency:
    """f1 [Hz] over the span, the per-segment frequencies [Hz] and their spread [% of f1]."""

    hz: float
    segments_hz: tuple[float, ...]
    change_pct: float

    @property
    def stationary(self) -> bool:
        """True when the fundamental changed by at most `MAX_CHANGE_PCT` over the span."""
        return self.change_pct <= MAX_CHANGE_PCT


def _smoothed(t: np.ndarray, x: np.ndarray, m: int) -> tuple[np.ndarray, np.ndarray]:
    """Means over consecutive groups of m samples (the tail that does not fill a group dropped)."""
    n = (t.shape[0] // m) * m
    return t[:n].reshape(-1, m).mean(axis=1), x[:n].reshape(-1, m).mean(axis=1)


def _slope(t: np.ndarray, y: np.ndarray) -> float:
    """Least-squares slope dy/dt."""
    tc = t - t.mean()
    den = float(np.dot(tc, tc))
    return float(np.dot(tc, y - y.mean())) / den if den > 0.0 else math.nan


def _segment_frequencies(ts: np.ndarray, angle: np.ndarray, f1: float) -> tuple[float, ...]:
    """(f1 over the span, then f1 over each of `SEGMENTS` equal parts of it) [Hz]: the angle at the parts' ends,
    each the mean over one electrical period centred there (a harmonic of f1 averages out exactly), differenced. A
    span shorter than two electrical periods is one part (no stationarity judged), f1 the least-squares estimate."""
    if not f1 > 0.0:
        return (f1, f1)
    step = float(ts[1] - ts[0])
    half = max(1, round(0.5 / f1 / step))  # half an electrical period in smoothed points
    first, last = half, ts.shape[0] - 1 - half
    if last - first < 2 * half:  # fewer than two electrical periods
        return (f1, f1)
    csum = np.concatenate(([0.0], np.cumsum(angle)))
    ends = np.linspace(first, last, SEGMENTS + 1).round().astype(np.int64)
    centred = (csum[ends + half + 1] - csum[ends - half]) / (2 * half + 1)
    rates = np.abs(np.diff(centred) / np.diff(ts[ends])) / (2.0 * math.pi)
    whole = abs(float(centred[-1] - centred[0]) / float(ts[ends[-1]] - ts[ends[0]])) / (2.0 * math.pi)
    return (whole, *(float(r) for r in rates))


def stator_frequency(t: np.ndarray, i_a: np.ndarray, i_b: np.ndarray, i_c: np.ndarray) -> StatorFrequency | None:
    """The stator electrical frequency of the three-phase set (i_a, i_b, i_c) [A] sampled at times t [s]; None
    when the span is too short (fewer than 2·SEGMENTS smoothed points) or the currents are ~ 0."""
    t = np.asarray(t, dtype=np.float64)
    if t.shape[0] < 2:
        return None
    span = float(t[-1] - t[0])
    if not span > 0.0:
        return None
    a, b, c = (np.asarray(x, dtype=np.float64) for x in (i_a, i_b, i_c))
    dt = span / (t.shape[0] - 1)
    m = max(1, round(SMOOTH_S / dt))
    z = (2.0 / 3.0) * (a - 0.5 * (b + c)) + 1j * ((b - c) / math.sqrt(3.0))
    ts, zs = _smoothed(t, z, m)
    if ts.shape[0] < 2 * SEGMENTS or float(np.mean(np.abs(zs))) < MIN_AMPLITUDE_A:
        return None
    angle = np.unwrap(np.angle(zs))
    f1 = abs(_slope(ts, angle)) / (2.0 * math.pi)
    if not math.isfinite(f1):
        return None
    f1, *seg = _segment_frequencies(ts, angle, f1)
    change = 100.0 * (max(seg) - min(seg)) / f1 if f1 > 0.0 else math.inf
    return StatorFrequency(hz=f1, segments_hz=tuple(seg), change_pct=change)


__all__ = ["MAX_CHANGE_PCT", "SEGMENTS", "SMOOTH_S", "StatorFrequency", "stator_frequency"]
