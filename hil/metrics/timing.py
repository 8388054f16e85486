"""Controller execution-time statistics (µs) and real-time flags over the metrics window."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pmsm_hil.hil.metrics._validate import require_fields, require_nonempty

SPLIT_NAMES = ("measure", "reference", "predict")


@dataclass(frozen=True)
class TimingStats:
    """Execution time (µs): median/p99/max of the total, medians of the measure/reference/predict split."""

    exec_median_us: float
    exec_p99_us: float
    exec_max_us: float
    split_median_us: dict[str, float]
    candidates_mean: float
    late_periods: int
    missed_periods: int


def timing_stats(periods: np.ndarray) -> TimingStats:
    """Execution-time statistics from `periods['exec_time_ns']` and `periods['exec_split_ns']`."""
    require_fields(periods, ("exec_time_ns", "exec_split_ns", "candidates", "late", "missed"), "periods")
    require_nonempty(periods, "periods")
    exec_us = np.asarray(periods["exec_time_ns"], dtype=np.float64) * 1e-3
    split = np.asarray(periods["exec_split_ns"], dtype=np.float64).reshape(periods.shape[0], -1) * 1e-3
    medians = {
        name: float(np.median(split[:, k])) for k, name in enumerate(SPLIT_NAMES) if k < split.shape[1]
    }
    return TimingStats(
        exec_median_us=float(np.median(exec_us)),
        exec_p99_us=float(np.percentile(exec_us, 99.0)),
        exec_max_us=float(exec_us.max()),
        split_median_us=medians,
        candidates_mean=float(np.mean(periods["candidates"], dtype=np.float64)),
        late_periods=int(np.count_nonzero(periods["late"])),
        missed_periods=int(np.count_nonzero(periods["missed"])),
    )
