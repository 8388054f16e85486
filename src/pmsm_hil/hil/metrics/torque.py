"""Torque metrics from the high-rate trace: mean, ripple RMS (eq. (20) of the MPTC paper) and peak-to-peak.

Eq. (20): T_ripple = sqrt( (1/n) Σ_j (T_j − T_av)² ), T_av the mean over the window. The trace may be
sampled non-uniformly, so each sample is weighted by its share of the window (trapezoidal weights); for
a uniformly sampled trace this is eq. (20) up to the half weight of the two end samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pmsm_hil.hil.metrics._validate import require_fields, require_nonempty, trace_times
from pmsm_hil.hil.metrics.moments import WeightedMoments


@dataclass(frozen=True)
class TorqueStats:
    """Torque statistics over the window (N·m)."""

    mean_nm: float
    ripple_rms_nm: float
    ripple_pp_nm: float


def torque_stats(trace: np.ndarray) -> TorqueStats:
    """Mean, ripple RMS (deviation from the mean, eq. (20)) and peak-to-peak of `trace['torque']` (N·m)."""
    require_fields(trace, ("t", "torque"), "trace")
    require_nonempty(trace, "trace")
    acc = WeightedMoments()
    acc.add(trace_times(trace["t"]), trace["torque"])
    return TorqueStats(mean_nm=acc.mean, ripple_rms_nm=acc.rms_deviation, ripple_pp_nm=acc.maximum - acc.minimum)
