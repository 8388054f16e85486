"""`compute_run_metrics`: the run's metrics dictionary over the metrics window (the CLI contract)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from pmsm_hil.hil.metrics._validate import require_fields, require_nonempty
from pmsm_hil.hil.metrics.streaming import LINK_KEYS, RAD_S_TO_RPM, SPEED_ZERO_HZ, WindowMetrics
from pmsm_hil.hil.records import PERIOD_DTYPE, TRACE_DTYPE


def compute_run_metrics(
    periods: np.ndarray,
    trace: np.ndarray,
    *,
    ts_s: float,
    pole_pairs: int,
    legs: int = 3,
    wall_time_s: float,
    link_stats: Mapping[str, int],
    deadline_misses: int,
    friction_nms: float = 0.0,
    inertia_kgm2: float = 0.0,
) -> dict[str, Any]:
    """Metrics of one run over the metrics window (`periods`: PERIOD_DTYPE, `trace`: TRACE_DTYPE layout).

    Raises `MetricsError` (naming the field) on bad input, `MetricsWindowError` on an empty window.
    THD values are None with `current_thd_note` and `not_applicable` when undefined (stator frequency ~ 0 or
    changing, window shorter than one electrical period). `friction_nms` B [N·m·s/rad] and `inertia_kgm2` J [kg·m²]:
    the mechanics, for the torque the drive must deliver (`torque_error_mean_nm`). Units: s, N·m, rpm, A, kHz, µs,
    Hz. The runner gets the same figures block by block from `WindowMetrics` (streaming.py), which this wraps.
    """
    require_fields(periods, tuple(PERIOD_DTYPE.names or ()), "periods")
    require_fields(trace, tuple(TRACE_DTYPE.names or ()), "trace")
    require_nonempty(periods, "periods")
    require_nonempty(trace, "trace")
    acc = WindowMetrics(trace.dtype)
    acc.add_periods(periods)
    acc.add_trace(trace)
    return acc.result(ts_s=ts_s, pole_pairs=pole_pairs, legs=legs, wall_time_s=wall_time_s,
                      link_stats=link_stats, deadline_misses=deadline_misses, friction_nms=friction_nms,
                      inertia_kgm2=inertia_kgm2)


__all__ = ["LINK_KEYS", "RAD_S_TO_RPM", "SPEED_ZERO_HZ", "compute_run_metrics"]
