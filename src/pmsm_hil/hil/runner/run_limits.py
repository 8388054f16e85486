"""Bounds of a run: before it starts, the speed reference against the motor's overspeed trip and the run's
length against what the records can count; after it, whether the speed reached its reference.

Speed reference: a completed run whose speed at the end of the metrics window (mean over its last 10 %)
differs from the reference over the same periods by more than `SPEED_BAND_PCT` of the reference (at least
`SPEED_BAND_MIN_RPM`) missed it (e.g. `--speed 2900` with niu2020 ends near 2160 rpm: the voltage limit);
the metrics say `speed_reference_missed` and the summary warns. 10 % keeps the speed dip a load step
leaves at the end of the bundled load-step scenarios (−5 %, −2 %) out of it. `SpeedTail` accumulates the
same figures block by block while the run goes on.

Length: the run streams its records (to the logger and the metrics, block by block), so memory does not
grow with its duration; the period index of the records is 32-bit, so a run has at most `MAX_PERIODS`
periods (≈ 5 days at Ts = 100 µs). A longer run is refused with an error naming the duration.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.runner.run_config import RunConfig

#: band around the speed reference [% of the reference] within which the speed counts as reached
SPEED_BAND_PCT = 10.0
#: smallest band [rpm] (references near standstill)
SPEED_BAND_MIN_RPM = 5.0
#: most periods of one run (`PERIOD_DTYPE.seq` is a uint32)
MAX_PERIODS = 2**32 - 1
_RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)


def check_run_limits(cfg: RunConfig, *, speed_option: str = "scenario speed_rpm",
                     duration_option: str = "scenario duration_s + settle_s") -> None:
    """ParameterError naming `speed_option` if a speed reference reaches the motor's `speed_trip_rpm`
    (every such run ends in an overspeed trip), or `duration_option` if the run has more than `MAX_PERIODS`
    periods."""
    sc, m = cfg.scenario, cfg.motor
    for rpm in {sc.speed_rpm, sc.start_speed_rpm}:
        if abs(rpm) >= m.speed_trip_rpm:
            raise ParameterError(
                f"{speed_option}: {rpm:g} rpm is at or beyond the motor's overspeed trip speed_trip_rpm = "
                f"{m.speed_trip_rpm:g} rpm ('{m.name}'); use a lower speed or --set speed_trip_rpm=...")
    periods = sc.total_s / cfg.ts_s
    if not math.isfinite(periods) or periods > MAX_PERIODS:
        raise ParameterError(
            f"{duration_option}: {sc.total_s:g} s of run (settling included) at Ts = {cfg.ts_s:g} s is {periods:.3g} "
            f"periods, more than the {MAX_PERIODS} a run can count: at most ≈ {MAX_PERIODS * cfg.ts_s:.4g} s")


class SpeedTail:
    """Mean speed and speed reference over the last 10 % of a metrics window of `window_periods` periods
    starting at period `window_start`, from blocks of period records (`add`) — for `speed_reference_check`."""

    def __init__(self, window_start: int, window_periods: int) -> None:
        self.first = window_start + window_periods - max(1, window_periods // 10)
        self.end = window_start + window_periods
        self.ref_sum = self.speed_sum = 0.0
        self.ref_n = self.speed_n = 0

    def add(self, block: npt.NDArray[np.void], first_period: int) -> None:
        """Add period records `first_period`, `first_period + 1`, ... (any block of the run)."""
        lo = max(self.first - first_period, 0)
        hi = min(self.end - first_period, block.shape[0])
        if hi <= lo:
            return
        tail = block[lo:hi]
        ref = np.asarray(tail["speed_ref"], dtype=np.float64)
        finite = np.isfinite(ref)
        self.ref_sum += float(np.sum(ref[finite]))
        self.ref_n += int(np.count_nonzero(finite))
        self.speed_sum += float(np.sum(tail["omega_m"], dtype=np.float64))
        self.speed_n += hi - lo

    def check(self) -> tuple[bool | None, str | None]:
        """(missed, warning); (None, None) without a speed reference or records."""
        if not (self.ref_n and self.speed_n):
            return None, None
        return _verdict(self.ref_sum / self.ref_n * _RAD_S_TO_RPM, self.speed_sum / self.speed_n * _RAD_S_TO_RPM)


def speed_reference_check(window: npt.NDArray[np.void]) -> tuple[bool | None, str | None]:
    """(missed, warning) for the window's PERIOD_DTYPE records; (None, None) without a speed reference."""
    if len(window) == 0:
        return None, None
    tail = SpeedTail(0, len(window))
    tail.add(window, 0)
    return tail.check()


def _verdict(ref: float, speed: float) -> tuple[bool | None, str | None]:
    """(missed, warning) for the mean speed against the mean reference [rpm] over the window's tail."""
    if not (math.isfinite(ref) and math.isfinite(speed)):
        return None, None
    band = max(SPEED_BAND_PCT / 100.0 * abs(ref), SPEED_BAND_MIN_RPM)
    if abs(speed - ref) <= band:
        return False, None
    return True, (f"speed reference missed: {speed:.0f} rpm at the end of the window against {ref:.0f} rpm "
                  f"({100.0 * (speed - ref) / ref if ref else math.inf:+.1f} %, band ±{SPEED_BAND_PCT:g} %): the "
                  "drive could not follow it (voltage or torque limit?)")


__all__ = ["MAX_PERIODS", "SPEED_BAND_PCT", "SpeedTail", "check_run_limits", "speed_reference_check"]
