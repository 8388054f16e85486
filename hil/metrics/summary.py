"""`compute_run_metrics`: the run's metrics dictionary over the metrics window (the CLI contract)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np
from pmsm_hil.hil.metrics._validate import require_fields, require_int, require_nonempty, require_positive
from pmsm_hil.hil.metrics.errors import MetricsError, MetricsWindowError
from pmsm_hil.hil.metrics.switching import switching_stats
from pmsm_hil.hil.metrics.thd import current_thd, fundamental_hz
from pmsm_hil.hil.metrics.timing import timing_stats
from pmsm_hil.hil.metrics.torque import torque_stats, weighted_mean
from pmsm_hil.hil.records import PERIOD_DTYPE, TRACE_DTYPE

LINK_KEYS = ("frames_tx", "frames_rx", "crc_errors", "lost", "late")
#: Below this electrical frequency (Hz) the speed is taken as zero and THD is reported as null.
SPEED_ZERO_HZ = 0.1
RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)


def _link(link_stats: Mapping[str, int]) -> dict[str, int]:
    if not isinstance(link_stats, Mapping):
        raise MetricsError(f"link_stats: expected a mapping, got {type(link_stats).__name__}")
    out: dict[str, int] = {}
    for key in LINK_KEYS:
        out[key] = require_int(link_stats.get(key, 0), f"link_stats[{key!r}]", 0)
    return out


def _thd(trace: np.ndarray, mean_omega: float, pole_pairs: int) -> dict[str, Any]:
    """THD block: phase a is the headline, phases b, c are listed too; null with a note if undefined."""
    f1 = fundamental_hz(mean_omega, pole_pairs)
    out: dict[str, Any] = {
        "current_thd_pct": None,
        "current_thd_total_pct": None,
        "current_fundamental_a": None,
        "current_fundamental_hz": f1,
        "current_thd_phases_pct": None,
        "current_thd_note": None,
    }
    if f1 < SPEED_ZERO_HZ:
        out["current_thd_note"] = (
            f"current_thd_pct: speed ~ 0 (mean {mean_omega * RAD_S_TO_RPM:.3g} rpm), THD undefined"
        )
        return out
    try:
        results = [
            current_thd(trace["t"], trace[ph], f1, field=f"trace.{ph}") for ph in ("i_a", "i_b", "i_c")
        ]
    except MetricsWindowError as exc:
        out["current_thd_note"] = str(exc)
        return out
    out.update(
        current_thd_pct=results[0].thd_pct,
        current_thd_total_pct=results[0].thd_total_pct,
        current_fundamental_a=results[0].fundamental_a,
        current_thd_phases_pct={
            ph: {"harmonics": r.thd_pct, "total": r.thd_total_pct}
            for ph, r in zip(("a", "b", "c"), results, strict=True)
        },
    )
    return out


def _distortion_rms(metrics: Mapping[str, Any]) -> float | None:
    """Absolute distortion of phase a [A RMS]: all non-fundamental content, fundamental_rms · THD_total.

    Beside THD because a large x-y (six-phase) or low-load current makes the fundamental a poor yardstick."""
    fund, thd_total = metrics.get("current_fundamental_a"), metrics.get("current_thd_total_pct")
    if fund is None or thd_total is None:
        return None
    return float(fund) / math.sqrt(2.0) * float(thd_total) / 100.0


def _torque_reference(periods: np.ndarray) -> tuple[float, str]:
    """Mean torque reference (N·m): finite `torque_ref` values if any (torque mode), else the load torque."""
    ref = np.asarray(periods["torque_ref"], dtype=np.float64)
    finite = np.isfinite(ref)
    if np.any(finite):
        return float(np.mean(ref[finite])), "torque_ref"
    return float(np.mean(periods["load_torque"], dtype=np.float64)), "load_torque"


def compute_run_metrics(
    periods: np.ndarray,
    trace: np.ndarray,
    *,
    ts_s: float,
    pole_pairs: int,
    legs: int = 3,
    wall_time_s: float,
    link_stats: Mapping[str, int],
    deadline_misses: int,
) -> dict[str, Any]:
    """Metrics of one run over the metrics window (`periods`: PERIOD_DTYPE, `trace`: TRACE_DTYPE).

    Raises `MetricsError` (naming the field) on bad input, `MetricsWindowError` on an empty window.
    THD values are None with `current_thd_note` when undefined (speed ~ 0 or window shorter than one
    electrical period). Units: s, N·m, rpm, A, kHz, µs, Hz.
    """
    require_fields(periods, tuple(PERIOD_DTYPE.names or ()), "periods")
    require_fields(trace, tuple(TRACE_DTYPE.names or ()), "trace")
    require_nonempty(periods, "periods")
    require_nonempty(trace, "trace")
    ts = require_positive(ts_s, "ts_s")
    p = require_int(pole_pairs, "pole_pairs", 1)
    misses = require_int(deadline_misses, "deadline_misses", 0)
    try:
        wall = float(wall_time_s)
    except (TypeError, ValueError):
        raise MetricsError(f"wall_time_s: expected a number, got {wall_time_s!r}") from None
    if not math.isfinite(wall) or wall < 0.0:
        raise MetricsError(f"wall_time_s: expected a finite value ≥ 0, got {wall_time_s!r}")

    n = int(periods.shape[0])
    torque = torque_stats(trace)
    mean_omega = weighted_mean(np.asarray(trace["t"], dtype=np.float64), trace["omega_m"])
    switching = switching_stats(periods, ts_s=ts, legs=legs)
    timing = timing_stats(periods)
    ref_mean, ref_name = _torque_reference(periods)

    metrics: dict[str, Any] = {
        "periods": n,
        "sim_time_s": n * ts,
        "wall_time_s": wall,
        "loop_rate_hz": n / wall if wall > 0.0 else None,
        "torque_mean_nm": torque.mean_nm,
        "torque_ripple_rms_nm": torque.ripple_rms_nm,
        "torque_ripple_pp_nm": torque.ripple_pp_nm,
        "torque_error_mean_nm": torque.mean_nm - ref_mean,
        "torque_error_reference": ref_name,
        "speed_mean_rpm": mean_omega * RAD_S_TO_RPM,
    }
    metrics.update(_thd(trace, mean_omega, p))
    metrics["current_distortion_rms_a"] = _distortion_rms(metrics)
    if "i_x" in (trace.dtype.names or ()):
        t = np.asarray(trace["t"], dtype=np.float64)
        xy_sq = np.asarray(trace["i_x"], dtype=np.float64) ** 2 + np.asarray(trace["i_y"], dtype=np.float64) ** 2
        metrics["xy_current_rms_a"] = math.sqrt(weighted_mean(t, xy_sq))
    metrics.update(
        {
            "switching_freq_khz": switching.freq_khz,
            "switching_freq_intra_khz": switching.freq_intra_khz,
            "exec_time_us": {
                "median": timing.exec_median_us,
                "p99": timing.exec_p99_us,
                "max": timing.exec_max_us,
            },
            "exec_split_us": dict(timing.split_median_us),
            "candidates_evaluated_mean": timing.candidates_mean,
            "narrow_pulses": switching.narrow_pulses,
            "narrow_pulses_gated": switching.narrow_pulses_gated,
            "deadline_misses": misses,
            "late_periods": timing.late_periods,
            "missed_periods": timing.missed_periods,
            "link": _link(link_stats),
        }
    )
    return metrics
