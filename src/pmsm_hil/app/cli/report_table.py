"""Human-readable metrics table for the terminal."""

from __future__ import annotations

from typing import Any

from pmsm_hil.hil.metrics.registry import CLI, in_view
from pmsm_hil.hil.runner.setpoint_hold import hold_line

#: (key, label, unit) of the summary rows: the registry's CLI view (dict-valued keys get their own lines below).
_ROWS = tuple((m.key, m.label, m.unit) for m in in_view(CLI) if m.sub is None)


def _med_p99_max(figures: dict[str, Any]) -> str:
    """"median / p99 / max" of a quantile mapping, each as `_fmt` prints it."""
    return f"{_fmt(figures.get('median'))} / {_fmt(figures.get('p99'))} / {_fmt(figures.get('max'))}"


def _fmt(value: Any) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def format_metrics(metrics: dict[str, Any]) -> str:
    """Two-column table of the main metrics: the setpoint verdict after the ending, metrics not applicable to the
    run as "n/a" with their reasons at the end."""
    lines = []
    found = metrics.get("not_applicable")
    na: dict[str, Any] = found if isinstance(found, dict) else {}
    for key, label, unit in _ROWS:
        if key == "setpoint_held":
            continue
        if key in metrics:
            if key in na and metrics[key] is None:
                lines.append(f"  {label:<24} n/a (not applicable)")
            else:
                lines.append(f"  {label:<24} {_fmt(metrics[key])} {unit}".rstrip())
        if key == "end_code" and (line := hold_line(metrics)) is not None:
            lines.append(f"  {line}")
    ex = metrics.get("exec_time_us")
    clock = metrics.get("mcu_clock_hz")
    if isinstance(ex, dict):  # an emulated MCU's figure is an estimate at its clock (qemu targets)
        label = f"exec est. @{clock / 1e6:g} MHz" if isinstance(clock, int | float) else "exec time med/p99/max"
        lines.append(f"  {label:<24} {_med_p99_max(ex)} µs")
    ins = metrics.get("exec_instructions")
    if isinstance(ins, dict):
        lines.append(f"  {'exec instructions':<24} {_med_p99_max(ins)} per step (med/p99/max)")
    isr = metrics.get("board_isr_time_us")
    if isinstance(isr, dict):  # the virtual board: handler cycles per period at the firmware's clock
        lines.append(f"  {'ISR time med/p99/max':<24} {_med_p99_max(isr)} µs per period")
    lat = metrics.get("lateness_us")
    if isinstance(lat, dict):
        lines.append(f"  {'lateness med/p99/max':<24} {_med_p99_max(lat)} µs")
    link = metrics.get("link")
    if isinstance(link, dict):
        lines.append(f"  {'link tx/rx/crc/lost/late':<24} {link.get('frames_tx')} / {link.get('frames_rx')} / "
                     f"{link.get('crc_errors')} / {link.get('lost')} / {link.get('late')}")
    cold = metrics.get("exec_time_first_us")
    if isinstance(cold, dict):
        lines.append(f"  {'exec cold start':<24} first {_fmt(cold.get('first'))} / max {_fmt(cold.get('max'))} µs "
                     f"(first {cold.get('periods')} periods, not in exec time)")
    reasons: dict[str, list[str]] = {}
    for key, why in na.items():
        if key in metrics and key not in ("setpoint_held", "setpoint_error"):
            reasons.setdefault(str(why), []).append(key)
    for why, keys in reasons.items():
        lines.append(f"  not applicable: {', '.join(keys)}: {why}")
    return "\n".join(lines)
