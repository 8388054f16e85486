"""Bounds of a run: before it starts, the speed reference against the motor's overspeed trip and the run's
buffers against the machine's memory; after it, whether the speed reached its reference.

Speed reference: a completed run whose speed at the end of the metrics window (mean over its last 10 %)
differs from the reference over the same periods by more than `SPEED_BAND_PCT` of the reference (at least
`SPEED_BAND_MIN_RPM`) missed it (e.g. `--speed 2900` with niu2020 ends near 2160 rpm: the voltage limit);
the metrics say `speed_reference_missed` and the summary warns. 10 % keeps the speed dip a load step
leaves at the end of the bundled load-step scenarios (−5 %, −2 %) out of it.

Memory: the loop keeps every period record (`PERIOD_DTYPE`), up to four raw frames per period
(`FRAME_DTYPE`) and the 2 µs trace of the metrics window in memory until the run ends, allocated up front;
`run_buffer_bytes` adds them up (≈ 3.0 kB per period at Ts = 100 µs: ≈ 30 MB per simulated second, most of
it the trace). A run whose buffers exceed `MEMORY_FRACTION` of the memory available now is refused with
an error naming the duration, instead of failing with MemoryError part-way through the allocation.
"""

from __future__ import annotations

import math
import os

import numpy as np
import numpy.typing as npt
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.records import FRAME_DTYPE, PERIOD_DTYPE
from pmsm_hil.hil.runner.run_config import RunConfig

#: band around the speed reference [% of the reference] within which the speed counts as reached
SPEED_BAND_PCT = 10.0
#: smallest band [rpm] (references near standstill)
SPEED_BAND_MIN_RPM = 5.0
#: share of the currently available memory the run's buffers may take
MEMORY_FRACTION = 0.5
#: raw frames reserved per period (measurement and command frames, six-phase profiles included)
FRAMES_PER_PERIOD = 4


def available_memory_bytes() -> int:
    """Memory available for new allocations now [bytes]: MemAvailable of /proc/meminfo, else physical RAM."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return 1 << 34  # 16 GiB when the platform tells nothing


def bytes_per_period(cfg: RunConfig) -> tuple[int, int]:
    """(bytes of every period, bytes of a metrics-window period) held by the run (module docstring)."""
    rows_per_period = math.ceil(cfg.ts_s / cfg.trace_dt_s) + 1
    every = PERIOD_DTYPE.itemsize + FRAMES_PER_PERIOD * FRAME_DTYPE.itemsize
    return every, rows_per_period * cfg.machine.layout.trace_dtype.itemsize


def run_buffer_bytes(cfg: RunConfig) -> float:
    """Bytes the run's in-memory records and trace take (see the module docstring)."""
    every, window = bytes_per_period(cfg)
    sc = cfg.scenario
    return (sc.total_s * every + sc.duration_s * window) / cfg.ts_s


def _size(n: float) -> str:
    if not math.isfinite(n):
        return "an unbounded amount"
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n / 1e3:.3g} kB"


def check_run_limits(cfg: RunConfig, *, speed_option: str = "scenario speed_rpm",
                     duration_option: str = "scenario duration_s + settle_s") -> None:
    """ParameterError naming `speed_option` if a speed reference reaches the motor's `speed_trip_rpm`
    (every such run ends in an overspeed trip), or `duration_option` if the buffers do not fit in memory."""
    sc, m = cfg.scenario, cfg.motor
    for rpm in {sc.speed_rpm, sc.start_speed_rpm}:
        if abs(rpm) >= m.speed_trip_rpm:
            raise ParameterError(
                f"{speed_option}: {rpm:g} rpm is at or beyond the motor's overspeed trip speed_trip_rpm = "
                f"{m.speed_trip_rpm:g} rpm ('{m.name}'); use a lower speed or --set speed_trip_rpm=...")
    need = run_buffer_bytes(cfg)
    have = available_memory_bytes()
    if need > MEMORY_FRACTION * have:
        per_s = sum(bytes_per_period(cfg)) / cfg.ts_s
        raise ParameterError(
            f"{duration_option}: {sc.total_s:g} s of run (settling included) at Ts = {cfg.ts_s:g} s needs "
            f"{_size(need)} of run buffers ({_size(per_s)} per simulated second), more than {MEMORY_FRACTION:.0%} "
            f"of the {_size(have)} available now: at most ≈ {MEMORY_FRACTION * have / per_s:.0f} s here")


def speed_reference_check(window: npt.NDArray[np.void]) -> tuple[bool | None, str | None]:
    """(missed, warning) for the window's PERIOD_DTYPE records; (None, None) without a speed reference."""
    if len(window) == 0:
        return None, None
    tail = window[-max(1, len(window) // 10):]
    rad_s_to_rpm = 60.0 / (2.0 * math.pi)
    with np.errstate(all="ignore"):
        ref = float(np.nanmean(tail["speed_ref"])) * rad_s_to_rpm if np.isfinite(tail["speed_ref"]).any() else math.nan
        speed = float(np.mean(tail["omega_m"])) * rad_s_to_rpm
    if not (math.isfinite(ref) and math.isfinite(speed)):
        return None, None
    band = max(SPEED_BAND_PCT / 100.0 * abs(ref), SPEED_BAND_MIN_RPM)
    if abs(speed - ref) <= band:
        return False, None
    return True, (f"speed reference missed: {speed:.0f} rpm at the end of the window against {ref:.0f} rpm "
                  f"({100.0 * (speed - ref) / ref if ref else math.inf:+.1f} %, band ±{SPEED_BAND_PCT:g} %): the "
                  "drive could not follow it (voltage or torque limit?)")


__all__ = ["MEMORY_FRACTION", "SPEED_BAND_PCT", "available_memory_bytes", "bytes_per_period", "check_run_limits",
           "run_buffer_bytes", "speed_reference_check"]
