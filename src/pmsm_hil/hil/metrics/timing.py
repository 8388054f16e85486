"""Controller execution-time statistics (µs) and real-time flags over the metrics window."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pmsm_hil.hil.metrics._validate import require_fields, require_nonempty
from pmsm_hil.hil.metrics.quantiles import IntQuantiles

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
    exec_us = IntQuantiles(1e-3)
    exec_us.add(periods["exec_time_ns"])
    split = np.asarray(periods["exec_split_ns"]).reshape(periods.shape[0], -1)
    medians: dict[str, float] = {}
    for k, name in enumerate(SPLIT_NAMES[: split.shape[1]]):
        acc = IntQuantiles(1e-3)
        acc.add(split[:, k])
        medians[name] = acc.median()
    return TimingStats(
        exec_median_us=exec_us.median(),
        exec_p99_us=exec_us.percentile(99.0),
        exec_max_us=exec_us.maximum(),
        split_median_us=medians,
        candidates_mean=float(np.mean(periods["candidates"], dtype=np.float64)),
        late_periods=int(np.count_nonzero(periods["late"])),
        missed_periods=int(np.count_nonzero(periods["missed"])),
    )
