"""Average switching frequency f_av = leg transitions / (2 · legs · time).

One switching period of a leg has two transitions (on and off), hence the factor 2. The total figure
counts every real gate transition in the window (including those at period boundaries); the intra-period
figure excludes the transitions that fall exactly on a period start (`boundary_transitions`).
Narrow pulses: leg pulses shorter than T_lim = 2·T_dead + T_mpw requested by the controller
(`narrow_pulses`) and those of them that reached the gate (`narrow_pulses_gated`, 0 if the records
predate the field).
Example: a three-vector symmetric sequence with 4 transitions per period at Ts = 100 µs on 3 legs gives
4 / (2 · 3 · 100 µs) = 6.67 kHz.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from pmsm_hil.hil.metrics._validate import require_fields, require_int, require_nonempty, require_positive
from pmsm_hil.hil.metrics.errors import MetricsError


@dataclass(frozen=True)
class SwitchingStats:
    """Average switching frequency per leg (kHz) and the transition counts behind it."""

    freq_khz: float
    freq_intra_khz: float
    transitions: int
    boundary_transitions: int
    narrow_pulses: int
    narrow_pulses_gated: int = 0


def switching_from_counts(periods: int, transitions: int, boundary: int, narrow: int, narrow_gated: int, *,
                          ts_s: float, legs: int = 3) -> SwitchingStats:
    """f_av (kHz) from transition counts over `periods` control periods of `ts_s` [s], `legs` inverter legs."""
    ts = require_positive(ts_s, "ts_s")
    n_legs = require_int(legs, "legs", 1)
    if boundary > transitions:
        raise MetricsError(
            f"periods.boundary_transitions: {boundary} exceeds periods.leg_transitions {transitions}"
        )
    scale = 1e-3 / (2.0 * n_legs * periods * ts)
    return SwitchingStats(freq_khz=transitions * scale, freq_intra_khz=(transitions - boundary) * scale,
                          transitions=transitions, boundary_transitions=boundary, narrow_pulses=narrow,
                          narrow_pulses_gated=narrow_gated)


def switching_stats(periods: np.ndarray, *, ts_s: float, legs: int = 3) -> SwitchingStats:
    """f_av (kHz) over `periods` (control period `ts_s`, s) for an inverter with `legs` legs."""
    require_fields(periods, ("leg_transitions", "boundary_transitions", "narrow_pulses"), "periods")
    require_nonempty(periods, "periods")
    gated = (int(np.sum(periods["narrow_pulses_gated"], dtype=np.int64))
             if "narrow_pulses_gated" in (periods.dtype.names or ()) else 0)
    return switching_from_counts(
        int(periods.shape[0]), int(np.sum(periods["leg_transitions"], dtype=np.int64)),
        int(np.sum(periods["boundary_transitions"], dtype=np.int64)),
        int(np.sum(periods["narrow_pulses"], dtype=np.int64)), gated, ts_s=ts_s, legs=legs)
