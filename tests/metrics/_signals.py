"""Synthetic period and trace records with known metric values."""

from __future__ import annotations

import numpy as np

from pmsm_hil.hil.records import PERIOD_DTYPE, TRACE_DTYPE


def make_trace(duration_s: float, dt_s: float, omega_m: float = 0.0) -> np.ndarray:
    """Uniform trace of `duration_s` with sample step `dt_s`, constant speed `omega_m` (rad/s)."""
    n = round(duration_s / dt_s) + 1
    tr = np.zeros(n, dtype=TRACE_DTYPE)
    tr["t"] = np.arange(n) * dt_s
    tr["omega_m"] = omega_m
    return tr


def make_periods(n: int, ts_s: float) -> np.ndarray:
    """`n` periods of `ts_s` with zero measurements and NaN torque reference."""
    p = np.zeros(n, dtype=PERIOD_DTYPE)
    p["seq"] = np.arange(n)
    p["t"] = np.arange(n) * ts_s
    p["torque_ref"] = np.nan
    return p


def three_phase(t: np.ndarray, f1: float, harmonics: dict[float, float]) -> tuple[np.ndarray, ...]:
    """Balanced phase currents: amplitude per harmonic order (1 = fundamental), shifted ±2π/3·h."""
    out = []
    for shift in (0.0, -2.0 * np.pi / 3.0, 2.0 * np.pi / 3.0):
        x = np.zeros_like(t)
        for order, amp in harmonics.items():
            x += amp * np.sin(2.0 * np.pi * order * f1 * t + order * shift + 0.1 * order)
        out.append(x)
    return tuple(out)
