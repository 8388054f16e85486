"""Refuses real-time configurations that the link's wire time cannot carry (link budget)."""

from __future__ import annotations

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.protocol.budget import LinkBudget, link_budget
from pmsm_hil.protocol.links import parse_spec

#: Links with no wire (in-process or loopback): their cost is measured, not budgeted.
_UNBOUNDED = ("virtual", "udp", "hiludp")


def wire_budget(spec: str, profile: str, rate_hz: float, phases: int = 3) -> LinkBudget | None:
    """Budget for a link SPEC at a control rate [Hz], or None for links without a wire limit."""
    ls = parse_spec(spec)
    kind = ls.kind.lower()
    if kind in _UNBOUNDED:
        return None
    opts = ls.options
    if kind in ("serial", "hilserial"):
        return link_budget("serial", phases, baud=int(opts.get("baudrate", 3_000_000)), rate_hz=rate_hz)
    bitrate = int(opts.get("bitrate", 1_000_000))
    data_bitrate = int(opts.get("data_bitrate", 5_000_000))
    return link_budget("canfd" if profile == "canfd" else "can", phases, bitrate=bitrate,
                       data_bitrate=data_bitrate, rate_hz=rate_hz)


def check_realtime_budget(spec: str, profile: str, ts_s: float, phases: int = 3) -> None:
    """Raise ParameterError naming the link when one period's frames take longer than Ts on the wire."""
    budget = wire_budget(spec, profile, 1.0 / ts_s, phases)
    if budget is None or budget.max_rate_hz >= 1.0 / ts_s:
        return
    raise ParameterError(
        f"--link {spec}: {budget.frames_per_period_up} + {budget.frames_per_period_down} frames per period need "
        f"{budget.wire_time_per_period_us:.0f} µs on the wire (worst case), more than Ts = {ts_s * 1e6:.0f} µs; "
        f"this link carries at most {budget.max_rate_hz:.0f} Hz (see `hil link-budget`)")
