"""Input checks shared by the metric modules (clear errors naming the field, never asserts)."""

from __future__ import annotations

import math

import numpy as np

from pmsm_hil.hil.metrics.errors import MetricsError, MetricsWindowError


def require_fields(arr: np.ndarray, fields: tuple[str, ...], name: str) -> None:
    """Raise `MetricsError` unless `arr` is a 1-D structured array holding `fields`."""
    if not isinstance(arr, np.ndarray) or arr.dtype.names is None:
        raise MetricsError(f"{name}: expected a structured numpy array, got {type(arr).__name__}")
    if arr.ndim != 1:
        raise MetricsError(f"{name}: expected a 1-D array, got shape {arr.shape}")
    missing = [f for f in fields if f not in arr.dtype.names]
    if missing:
        raise MetricsError(f"{name}: missing field(s) {', '.join(missing)}")


def require_nonempty(arr: np.ndarray, name: str, minimum: int = 1) -> None:
    """Raise `MetricsWindowError` if `arr` has fewer than `minimum` records."""
    if arr.shape[0] < minimum:
        raise MetricsWindowError(
            f"{name}: metrics window holds {arr.shape[0]} record(s), at least {minimum} needed"
        )


def require_positive(value: float, name: str) -> float:
    """Return `value` as float if finite and > 0, else raise `MetricsError` naming it."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise MetricsError(f"{name}: expected a number, got {value!r}") from None
    if not math.isfinite(x) or x <= 0.0:
        raise MetricsError(f"{name}: expected a finite value > 0, got {value!r}")
    return x


def require_int(value: object, name: str, minimum: int) -> int:
    """Return `value` as int if it is an integer ≥ `minimum`, else raise `MetricsError` naming it."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise MetricsError(f"{name}: expected an integer, got {value!r}")
    if int(value) < minimum:
        raise MetricsError(f"{name}: expected an integer ≥ {minimum}, got {value!r}")
    return int(value)


def trace_times(t: np.ndarray, name: str = "trace.t") -> np.ndarray:
    """Return `t` as float64 after checking it is finite and strictly increasing."""
    times = np.asarray(t, dtype=np.float64)
    if not np.all(np.isfinite(times)):
        raise MetricsError(f"{name}: contains non-finite times")
    if times.shape[0] > 1 and np.any(np.diff(times) <= 0.0):
        raise MetricsError(f"{name}: times must be strictly increasing")
    return times
