"""Human-readable metrics table for the terminal."""

from __future__ import annotations

from typing import Any

_ROWS = (
    ("controller", "controller", ""), ("scenario", "scenario", ""), ("periods", "periods (window)", ""),
    ("speed_mean_rpm", "speed mean", "rpm"), ("torque_mean_nm", "torque mean", "N·m"),
    ("torque_error_mean_nm", "torque error mean", "N·m"), ("torque_ripple_rms_nm", "torque ripple RMS", "N·m"),
    ("torque_ripple_pp_nm", "torque ripple p-p", "N·m"), ("current_fundamental_a", "current fundamental", "A"),
    ("current_thd_pct", "current THD (h2..40)", "%"), ("current_thd_total_pct", "current THD (all)", "%"),
    ("switching_freq_khz", "switching freq f_av", "kHz"), ("switching_freq_intra_khz", "f_av intra-period", "kHz"),
    ("candidates_evaluated_mean", "candidates / step", ""), ("narrow_pulses", "narrow pulses", ""),
    ("deadline_misses", "deadline misses", ""), ("loop_rate_hz", "loop rate", "periods/s"),
    ("end_reason", "end", ""),
)


def _fmt(value: Any) -> str:
    if value is None:
        return "n/a"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def format_metrics(metrics: dict[str, Any]) -> str:
    """Two-column table of the main metrics."""
    lines = []
    for key, label, unit in _ROWS:
        if key in metrics:
            lines.append(f"  {label:<24} {_fmt(metrics[key])} {unit}".rstrip())
    ex = metrics.get("exec_time_us")
    if isinstance(ex, dict):
        lines.append(f"  {'exec time med/p99/max':<24} {_fmt(ex.get('median'))} / {_fmt(ex.get('p99'))} / "
                     f"{_fmt(ex.get('max'))} µs")
    lat = metrics.get("lateness_us")
    if isinstance(lat, dict):
        lines.append(f"  {'lateness med/p99/max':<24} {_fmt(lat.get('median'))} / {_fmt(lat.get('p99'))} / "
                     f"{_fmt(lat.get('max'))} µs")
    link = metrics.get("link")
    if isinstance(link, dict):
        lines.append(f"  {'link tx/rx/crc/lost/late':<24} {link.get('frames_tx')} / {link.get('frames_rx')} / "
                     f"{link.get('crc_errors')} / {link.get('lost')} / {link.get('late')}")
    return "\n".join(lines)
