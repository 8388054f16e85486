"""Closed-loop runs of a compare preset through the runner (`run_closed_loop`), one row per run."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from pmsm_hil.hil.compare.preset import ComparePreset
from pmsm_hil.hil.errors import HilError
from pmsm_hil.hil.mechanics import RPM_TO_RAD_S
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario

#: metrics copied from the runner's metrics into a row
ROW_METRICS = ("torque_ripple_rms_nm", "torque_ripple_pp_nm", "current_thd_pct", "current_thd_total_pct",
               "switching_freq_khz", "candidates_evaluated_mean", "torque_error_mean_nm", "candidate_miss_rate",
               "speed_mean_rpm")
#: equal-f_av search: relative tolerance and iteration limit
FAV_TOL = 0.03
FAV_ITER = 5

Progress = Callable[[str], None]


@dataclass(slots=True)
class CompareResult:
    """Rows (one per run, 'group' main or equal_fav) and speed/torque series of accel presets."""

    preset: ComparePreset
    rows: list[dict[str, Any]] = field(default_factory=list)
    series: dict[str, dict[str, list[float]]] = field(default_factory=dict)


def _config(p: ComparePreset, controller: str, ts_s: float, point: dict[str, float]) -> RunConfig:
    motor = load_motor(p.motor)
    overrides: dict[str, Any] = {"settle_s": p.settle_s, "duration_s": p.duration_s, "speed_rpm": p.speed_rpm,
                                 "load_nm": p.load_nm, **point}
    scenario = load_scenario(p.scenario).with_overrides(**overrides)
    return RunConfig(motor=motor, scenario=scenario, controller=controller, ts_s=ts_s)


def _reach_time(periods: np.ndarray, target_rpm: float, frac: float = 0.98) -> float | None:
    """First time [s] the speed reaches frac of the target, or None."""
    rpm = periods["omega_m"] / RPM_TO_RAD_S
    idx = np.nonzero(rpm >= frac * target_rpm)[0]
    return float(periods["t"][idx[0]]) if len(idx) else None


def run_one(p: ComparePreset, controller: str, ts_s: float, point: dict[str, float],
            group: str = "main") -> tuple[dict[str, Any], np.ndarray]:
    """One closed-loop run; the row and the period records."""
    cfg = _config(p, controller, ts_s, point)
    res = run_closed_loop(cfg)
    m = res.metrics
    row: dict[str, Any] = {"group": group, "controller": controller, "ts_us": round(ts_s * 1e6, 3),
                           "speed_rpm": cfg.scenario.speed_rpm, "load_nm": cfg.scenario.load_nm}
    for key in ROW_METRICS:
        row[key] = m.get(key)
    split = m.get("exec_split_us")
    row["exec_time_us_median"] = (m.get("exec_time_us") or {}).get("median")
    row["exec_split_us_median"] = split.get("median") if isinstance(split, dict) else None
    periods = res.outcome.periods.all()
    row["t_reach_98pct_s"] = _reach_time(periods, cfg.scenario.speed_rpm)
    row["end_reason"] = m.get("end_reason")
    return row, periods


def _points(p: ComparePreset) -> list[dict[str, float]]:
    if p.sweep_key is None:
        return [{}]
    return [{p.sweep_key: v} for v in p.sweep_values]


def _equal_fav(p: ComparePreset, result: CompareResult, progress: Progress) -> None:
    """Shorten the adjusted controller's Ts until its f_av matches the reference's (secant on 1/Ts)."""
    assert p.equal_fav is not None  # checked by the caller
    ref_name, adj_name = p.equal_fav
    for point in _points(p):
        ref = next((r for r in result.rows if r["controller"] == ref_name and r["group"] == "main"
                    and all(r[k] == v for k, v in point.items())), None)
        if ref is None or not ref["switching_freq_khz"]:
            continue
        target = float(ref["switching_freq_khz"])
        ts = p.ts_s
        row: dict[str, Any] | None = None
        for _ in range(FAV_ITER):
            row, _periods = run_one(p, adj_name, ts, point, group="equal_fav")
            fav = float(row["switching_freq_khz"] or 0.0)
            progress(f"  equal f_av: {adj_name} at Ts = {ts * 1e6:.1f} µs -> {fav:.3f} kHz (target {target:.3f})")
            if fav <= 0.0 or abs(fav - target) <= FAV_TOL * target:
                break
            ts_new = round(ts * fav / target * 1e7) / 1e7  # f_av ∝ 1/Ts; 0.1 µs grid
            ts_new = min(max(ts_new, 5e-6), 1e-2)
            if math.isclose(ts_new, ts):
                break
            ts = ts_new
        if row is not None:
            row["equal_fav_target_khz"] = target
            result.rows.append(row)


def run_preset(p: ComparePreset, *, controllers: list[str] | None = None,
               progress: Progress | None = None) -> CompareResult:
    """Run every controller at every operating point of the preset, then the equal-f_av search."""
    say = progress or (lambda _msg: None)
    result = CompareResult(p)
    names = controllers or list(p.controllers)
    for point in _points(p):
        for name in names:
            label = ", ".join(f"{k}={v:g}" for k, v in point.items())
            say(f"run {name} {label}".rstrip())
            try:
                row, periods = run_one(p, name, p.ts_s, point)
            except HilError as exc:
                raise HilError(f"{name} {label}: {exc}") from None
            result.rows.append(row)
            if p.figure == "accel":
                step = max(1, len(periods) // 3000)
                result.series[name] = {"t": periods["t"][::step].tolist(),
                                       "speed_rpm": (periods["omega_m"][::step] / RPM_TO_RAD_S).tolist(),
                                       "torque_nm": periods["torque"][::step].tolist()}
    if p.equal_fav is not None:
        _equal_fav(p, result, say)
    return result
