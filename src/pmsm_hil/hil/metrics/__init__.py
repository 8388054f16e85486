"""Run metrics over the metrics window: torque ripple, current THD, switching frequency, timing."""

from __future__ import annotations

from pmsm_hil.hil.metrics.errors import MetricsError, MetricsWindowError
from pmsm_hil.hil.metrics.summary import compute_run_metrics
from pmsm_hil.hil.metrics.switching import SwitchingStats, switching_stats
from pmsm_hil.hil.metrics.thd import ThdResult, current_thd, fundamental_hz
from pmsm_hil.hil.metrics.timing import TimingStats, timing_stats
from pmsm_hil.hil.metrics.torque import TorqueStats, torque_stats

__all__ = [
    "MetricsError",
    "MetricsWindowError",
    "SwitchingStats",
    "ThdResult",
    "TimingStats",
    "TorqueStats",
    "compute_run_metrics",
    "current_thd",
    "fundamental_hz",
    "switching_stats",
    "timing_stats",
    "torque_stats",
]
