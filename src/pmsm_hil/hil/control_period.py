"""The control period Ts: its one range and its one check, for the plant, the run options and the benches."""

from __future__ import annotations

import math

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.protocol.codec import MAX_DURATION_NS

#: Shortest control period [s]
MIN_TS_S = 5e-6
#: Shortest period the plant steps [s]: the run's control period starts at MIN_TS_S; a plant built outside a run
#: (the tests' reference plants that end a period exactly at a trace row's time) may step down to 1 µs
PLANT_MIN_TS_S = 1e-6
#: Longest control period [s]: what a Command's duration field carries
MAX_TS_S = MAX_DURATION_NS * 1e-9
#: The range in words (error messages, `--help`)
TS_RANGE_WORDS = (f"between 5 µs and {MAX_DURATION_NS / 1e6:.6f} ms (a Command's duration field carries at most "
                  f"{MAX_DURATION_NS} ns)")


def check_control_period(ts_s: object, name: str = "--ts", shortest_s: float = MIN_TS_S) -> int:
    """The control period `ts_s` [s] in ns; ParameterError naming `name` when it is not a finite number in
    [`shortest_s`, MAX_TS_S] or not a whole number of ns."""
    if isinstance(ts_s, bool) or not isinstance(ts_s, int | float) or not math.isfinite(ts_s) \
            or not shortest_s <= ts_s <= MAX_TS_S:
        words = TS_RANGE_WORDS if shortest_s == MIN_TS_S else TS_RANGE_WORDS.replace(
            "5 µs", f"{shortest_s * 1e6:g} µs")
        raise ParameterError(f"{name} must be {words}, got {ts_s!r}")
    ns = round(ts_s * 1e9)
    if abs(ns - ts_s * 1e9) > 1e-3:
        raise ParameterError(f"{name} must be a whole number of ns, got {ts_s} s")
    return ns


__all__ = ["MAX_TS_S", "MIN_TS_S", "PLANT_MIN_TS_S", "TS_RANGE_WORDS", "check_control_period"]
