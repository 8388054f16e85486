"""Refuses real-time configurations that the link's wire time cannot carry (link budget)."""

from __future__ import annotations

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.protocol.links import link_kind, parse_spec
from pmsm_hil.protocol.links.budget import LinkBudget


def wire_budget(spec: str, rate_hz: float, phases: int = 3) -> LinkBudget | None:
    """Budget for a link SPEC at a control rate [Hz] with `phases`-phase frames, or None for links without a
    wire limit (the link kind's registry entry decides)."""
    ls = parse_spec(spec)
    return link_kind(ls).budget(ls, rate_hz, phases)


def check_realtime_budget(spec: str, ts_s: float, phases: int = 3) -> None:
    """Raise ParameterError naming the link when one period's frames take longer than Ts on the wire."""
    budget = wire_budget(spec, 1.0 / ts_s, phases)
    if budget is None or budget.max_rate_hz >= 1.0 / ts_s:
        return
    raise ParameterError(
        f"--link {spec}: {budget.frames_per_period_up} + {budget.frames_per_period_down} frames per period need "
        f"{budget.wire_time_per_period_us:.0f} µs on the wire (worst case), more than Ts = {ts_s * 1e6:.0f} µs; "
        f"this link carries at most {budget.max_rate_hz:.0f} Hz (see `hil link-budget`)")
