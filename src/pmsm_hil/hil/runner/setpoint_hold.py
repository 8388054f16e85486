"""The setpoint verdict: did the drive hold its setpoint at the end of the metrics window?

`hil run` drives the target in speed mode (Setpoint mode 0), so the setpoint is the speed reference: the mean
speed over the hold span (the last 10 % of the metrics window, the span of `SpeedTail`: what the drive settled
to after the scenario's steps) against the mean reference over the same periods. Held when
|error| ≤ tolerance · |reference| (the tolerance `--hold-tolerance` / the scenario's `hold_tolerance_pct`,
default `DEFAULT_HOLD_TOLERANCE_PCT`), with a floor of `HOLD_FLOOR_RPM` for references near standstill.
A run that did not complete (or has no reference in the span) has no verdict: null, the reason in
`not_applicable`.
"""

from __future__ import annotations

import math
from typing import Any

from pmsm_hil.hil.runner.run_limits import SpeedTail
from pmsm_hil.hil.runner.scenario import DEFAULT_HOLD_TOLERANCE_PCT

#: smallest tolerance band [rpm] (references near standstill)
HOLD_FLOOR_RPM = 5.0
_RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)
#: the keys the verdict sets
HOLD_KEYS = ("setpoint_mode", "setpoint_held", "setpoint_error", "hold_tolerance_pct")


def setpoint_verdict(tail: SpeedTail, tolerance_pct: float, *, completed: bool) -> tuple[dict[str, Any], str | None]:
    """(metrics keys of the verdict, not-applicable reason or None). `setpoint_error`: `{absolute, relative_pct,
    unit, reference, measured}` (measured − reference, in the setpoint's unit)."""
    out: dict[str, Any] = {"setpoint_mode": "speed", "setpoint_held": None, "setpoint_error": None,
                           "hold_tolerance_pct": tolerance_pct}
    if not completed:
        return out, "the run did not complete: no setpoint verdict"
    if not (tail.ref_n and tail.speed_n):
        return out, "no speed reference over the hold span"
    ref = tail.ref_sum / tail.ref_n * _RAD_S_TO_RPM
    speed = tail.speed_sum / tail.speed_n * _RAD_S_TO_RPM
    if not (math.isfinite(ref) and math.isfinite(speed)):
        return out, "the speed or its reference is not finite over the hold span"
    err = speed - ref
    out["setpoint_error"] = {"absolute": err, "relative_pct": 100.0 * err / ref if ref else None, "unit": "rpm",
                             "reference": ref, "measured": speed}
    out["setpoint_held"] = abs(err) <= max(tolerance_pct / 100.0 * abs(ref), HOLD_FLOOR_RPM)
    return out, None


def hold_line(metrics: dict[str, Any]) -> str | None:
    """One line for the summary: the verdict and its error, or why there is none (None: no verdict keys)."""
    if "setpoint_held" not in metrics:
        return None
    held, err, tol = metrics.get("setpoint_held"), metrics.get("setpoint_error"), metrics.get("hold_tolerance_pct")
    if held is None:
        why = (metrics.get("not_applicable") or {}).get("setpoint_held", "not evaluated")
        return f"setpoint held: n/a ({why})"
    assert isinstance(err, dict)
    rel = err.get("relative_pct")
    rel_text = f", {rel:+.2f} %" if isinstance(rel, float) else ""
    return (f"setpoint held: {'yes' if held else 'NO'} — speed {err['measured']:.1f} rpm vs {err['reference']:.1f} "
            f"rpm ({err['absolute']:+.1f} rpm{rel_text}; tolerance ±{tol:g} %, last 10 % of the window)")


__all__ = ["DEFAULT_HOLD_TOLERANCE_PCT", "HOLD_FLOOR_RPM", "HOLD_KEYS", "hold_line", "setpoint_verdict"]
