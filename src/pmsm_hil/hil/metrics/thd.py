"""Current THD from an FFT over an integer number of fundamental electrical periods.

The fundamental frequency comes from the mean mechanical speed, f1 = p·n/60 (n in rpm), i.e.
f1 = p·|ω_m|/(2π). The largest integer number M of electrical periods that fits the window is taken
from the window start, and the current is resampled (linear interpolation) onto an exact periodic grid
of N = M·K points covering exactly M/f1 seconds, so the fundamental lands on bin M and harmonic h on
bin h·M (no leakage from the window). K, the points per electrical period, is the smallest 5-smooth
number (2^a·3^b·5^c) that is at least the trace's samples per period (and 2·max_harmonic + 2), so the FFT
never runs at a length with a large prime factor (993 532 = 2²·149·1667 took 15× longer than 1 005 750).
Two figures are reported:

* `thd_pct`: integer harmonics 2..max_harmonic, sqrt(Σ_h A_h²)/A_1 · 100;
* `thd_total_pct`: all non-fundamental content except DC up to half the trace rate,
  sqrt(Σ_{k≠0,M} A_k²)/A_1 · 100 (includes interharmonics and switching-frequency content).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pmsm_hil.hil.metrics._validate import require_positive, trace_times
from pmsm_hil.hil.metrics.errors import MetricsError, MetricsWindowError

DEFAULT_MAX_HARMONIC = 40


@dataclass(frozen=True)
class ThdResult:
    """THD of one current over the chosen span."""

    thd_pct: float
    thd_total_pct: float
    fundamental_a: float
    fundamental_hz: float
    electrical_periods: int
    samples: int


def fundamental_hz(omega_m_mean: float, pole_pairs: int) -> float:
    """Electrical fundamental frequency (Hz) from the mean mechanical speed `omega_m_mean` (rad/s)."""
    return pole_pairs * abs(omega_m_mean) / (2.0 * math.pi)


def next_smooth(n: int) -> int:
    """Smallest 5-smooth integer (2^a·3^b·5^c) ≥ n (n ≥ 1): a fast FFT length."""
    best = 1 << max(n - 1, 0).bit_length()  # a power of two ≥ n
    p5 = 1
    while p5 < best:
        p35 = p5
        while p35 < best:
            m = p35
            while m < n:
                m *= 2
            best = min(best, m)
            p35 *= 3
        p5 *= 5
    return best


def amplitude_spectrum(x: np.ndarray) -> np.ndarray:
    """One-sided amplitude spectrum of the real periodic sequence `x` (same unit as x, peak)."""
    n = x.shape[0]
    amp: np.ndarray = np.abs(np.fft.rfft(x)) * (2.0 / n)
    amp[0] /= 2.0
    if n % 2 == 0:
        amp[-1] /= 2.0
    return amp


def current_thd(
    t: np.ndarray,
    current: np.ndarray,
    f1_hz: float,
    *,
    max_harmonic: int = DEFAULT_MAX_HARMONIC,
    field: str = "trace.i_a",
) -> ThdResult:
    """THD (two ways) and fundamental amplitude (A) of `current` sampled at times `t` (s).

    Raises `MetricsWindowError` naming `field` if the window is shorter than one electrical period.
    """
    f1 = require_positive(f1_hz, f"{field}: fundamental frequency")
    times = trace_times(t)
    x = np.asarray(current, dtype=np.float64)
    if x.shape != times.shape:
        raise MetricsError(f"{field}: {x.shape[0]} samples but {times.shape[0]} times")
    if times.shape[0] < 2:
        raise MetricsWindowError(f"{field}: at least 2 samples needed, got {times.shape[0]}")
    if not np.all(np.isfinite(x)):
        raise MetricsError(f"{field}: contains non-finite samples")
    span = float(times[-1] - times[0])
    periods = math.floor(span * f1 * (1.0 + 1e-12))
    if periods < 1:
        raise MetricsWindowError(
            f"{field}: window {span:.6g} s is shorter than one electrical period "
            f"{1.0 / f1:.6g} s (f1 = {f1:.6g} Hz)"
        )
    trace_rate = (times.shape[0] - 1) / span
    per_period = next_smooth(max(2 * max_harmonic + 2, math.ceil(trace_rate / f1)))
    n = periods * per_period
    duration = periods / f1
    grid = times[0] + np.arange(n, dtype=np.float64) * (duration / n)
    amp = amplitude_spectrum(np.interp(grid, times, x))
    fundamental = float(amp[periods])
    if fundamental <= 0.0:
        raise MetricsError(f"{field}: fundamental amplitude at {f1:.6g} Hz is zero")
    harmonic_bins = [h * periods for h in range(2, max_harmonic + 1) if h * periods < amp.shape[0]]
    harmonic_power = float(np.sum(amp[harmonic_bins] ** 2))
    k_max = min(amp.shape[0] - 1, math.floor(trace_rate / 2.0 * duration))
    band = amp[1 : k_max + 1] ** 2
    total_power = float(np.sum(band)) - fundamental**2
    return ThdResult(
        thd_pct=100.0 * math.sqrt(harmonic_power) / fundamental,
        thd_total_pct=100.0 * math.sqrt(max(total_power, 0.0)) / fundamental,
        fundamental_a=fundamental,
        fundamental_hz=f1,
        electrical_periods=periods,
        samples=n,
    )
