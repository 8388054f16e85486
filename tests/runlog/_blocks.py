"""Deterministic period, frame and trace blocks for the run-log tests."""

from __future__ import annotations

import numpy as np

from pmsm_hil.hil.records import FRAME_DTYPE, PERIOD_DTYPE, TRACE_DTYPE

TS = 100e-6
TRACE_PER_PERIOD = 50


def period_block(start: int, n: int) -> np.ndarray:
    """Periods `start`..`start+n-1` with varied values in every field."""
    rng = np.random.default_rng(start)
    b = np.zeros(n, dtype=PERIOD_DTYPE)
    b["seq"] = np.arange(start, start + n)
    b["t"] = b["seq"] * TS
    for name in PERIOD_DTYPE.names or ():
        if name in ("t", "seq"):
            continue
        field = b[name]
        if field.dtype.kind == "f":
            b[name] = rng.normal(0.0, 10.0, field.shape)
        else:
            b[name] = rng.integers(0, np.iinfo(field.dtype).max, field.shape, endpoint=True)
    return b


def trace_block(start_period: int, periods: int) -> np.ndarray:
    """Trace samples covering `periods` periods from period `start_period`."""
    n = periods * TRACE_PER_PERIOD
    tr = np.zeros(n, dtype=TRACE_DTYPE)
    tr["t"] = start_period * TS + np.arange(n) * (TS / TRACE_PER_PERIOD)
    tr["i_a"] = np.sin(2 * np.pi * 66.7 * tr["t"])
    tr["i_b"] = np.sin(2 * np.pi * 66.7 * tr["t"] - 2.0)
    tr["i_c"] = -tr["i_a"] - tr["i_b"]
    tr["torque"] = 4.0 + 0.1 * np.cos(tr["t"] * 1e4)
    tr["omega_m"] = 104.7
    return tr


def frame_block(start_period: int, periods: int) -> np.ndarray:
    """Two frames per period (one each direction), CAN FD every other period."""
    n = 2 * periods
    fr = np.zeros(n, dtype=FRAME_DTYPE)
    k = np.arange(n)
    fr["seq"] = start_period * 2 + k
    fr["t"] = (start_period + k // 2) * TS
    fr["direction"] = k % 2
    fr["arbitration_id"] = 0x100 + (k % 2)
    fr["is_fd"] = (k // 2) % 2
    fr["length"] = np.where(fr["is_fd"] == 1, 64, 8)
    fr["data"] = (k[:, None] + np.arange(64)[None, :]) % 256
    fr["data"][fr["is_fd"] == 0, 8:] = 0
    return fr
