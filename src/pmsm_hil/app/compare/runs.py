"""Closed-loop runs of a compare preset through the runner (`run_closed_loop`), one row per run."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from pmsm_hil.app.compare.preset import ComparePreset, Variant
from pmsm_hil.app.sweep.engines import Engine, InlineEngine
from pmsm_hil.hil.errors import HilError
from pmsm_hil.hil.mechanics import RPM_TO_RAD_S
from pmsm_hil.hil.metrics.registry import RUN, WINDOW, row_keys
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig, param_id
from pmsm_hil.hil.runner.run_options import MAX_TS_S, MIN_TS_S
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.sim_target.firmware import CONTROLLERS

#: metrics copied from the runner's metrics into a row (the registry's compare-row view, run sources)
ROW_METRICS = row_keys(source=(WINDOW, RUN))
#: equal-f_av search: relative tolerance and iteration limit
FAV_TOL = 0.03
FAV_ITER = 5

Progress = Callable[[str], None]
#: where a run logs run.mcap (with the 2 µs trace) and metrics.json, or None (not logged):
#: (spec, operating point, initial rotor angle [rad], group) -> directory
RunDirFor = Callable[[Variant, dict[str, float], float, str], Path | None]


@dataclass(slots=True)
class CompareResult:
    """Rows (one per run, 'group' main or equal_fav) and speed/torque series of accel presets."""

    preset: ComparePreset
    rows: list[dict[str, Any]] = field(default_factory=list)
    series: dict[str, dict[str, list[float]]] = field(default_factory=dict)


#: run option of each operating-point key of a preset (SWEEP_KEYS)
_POINT_OPTIONS = {"speed_rpm": "speed", "load_nm": "load"}


def _read_params(controller: str, params: dict[str, float]) -> dict[str, float]:
    """The parameters `controller` reads (all for one outside the firmware's table)."""
    info = next((c for c in CONTROLLERS if c.name == controller), None)
    return dict(params) if info is None else {k: v for k, v in params.items() if int(param_id(k)) in info.params}


def _config(p: ComparePreset, spec: Variant, ts_s: float, point: dict[str, float], theta0_rad: float) -> RunConfig:
    """The run of `spec` at `point` and initial rotor angle `theta0_rad`, through the one path of run options."""
    params = {**p.params, **spec.params}
    read = _read_params(spec.controller, params)
    values: dict[str, Any] = {"motor": p.motor, "scenario": p.scenario, "controller": spec.controller, "ts": ts_s,
                              "settle": p.settle_s, "duration": p.duration_s, "speed": p.speed_rpm, "load": p.load_nm,
                              "theta0": theta0_rad, "param": read, "no_log": True}
    values.update({_POINT_OPTIONS[key]: value for key, value in point.items()})
    cfg = RunConfig.from_options({k: v for k, v in values.items() if v is not None},
                                 dict.fromkeys(values, f"compare preset {p.name}"))
    if read == params:
        return cfg
    # a preset also sends parameters a controller does not read, which `hil run --param` refuses: the preset's
    # parameters are for the controllers that use them, and a variant may check that one leaves a controller as it is
    return replace(cfg, controller_params={k: cfg.controller_params.get(k, v) for k, v in params.items()})


def evaluation_e(row: dict[str, Any], torque_base_nm: float, fav_base_khz: float,
                 fav_key: str = "switching_freq_khz") -> float | None:
    """Eq. (12) of 003_7bbad73a6f78337e.txt: E = ΔT_pp / T_base + f_av / f_base + THD[%] / 100 (THD h2..40);
    None if a figure is missing."""
    pp, fav, thd = row.get("torque_ripple_pp_nm"), row.get(fav_key), row.get("current_thd_pct")
    if pp is None or fav is None or thd is None:
        return None
    return float(pp) / torque_base_nm + float(fav) / fav_base_khz + float(thd) / 100.0


def _reach_time(periods: np.ndarray, target_rpm: float, frac: float = 0.98) -> float | None:
    """First time [s] the speed reaches frac of the target, or None."""
    rpm = periods["omega_m"] / RPM_TO_RAD_S
    idx = np.nonzero(rpm >= frac * target_rpm)[0]
    return float(periods["t"][idx[0]]) if len(idx) else None


def run_one(p: ComparePreset, spec: Variant | str, ts_s: float, point: dict[str, float],
            group: str = "main", theta0_rad: float = 0.0,
            out_dir: Path | None = None) -> tuple[dict[str, Any], np.ndarray]:
    """One closed-loop run; the row and the period records. `out_dir`: log the run there (run.mcap with
    the trace, metrics.json; the row's `run_dir`)."""
    if isinstance(spec, str):
        spec = Variant(spec, spec)
    cfg = _config(p, spec, ts_s, point, theta0_rad)
    if out_dir is not None:
        cfg = replace(cfg, out_dir=out_dir, log_trace=True)
    res = run_closed_loop(cfg)
    m = res.metrics
    periods = res.outcome.periods.all()
    if m.get("speed_mean_rpm") is None:  # ended before the metrics window (a trip): a row without metrics
        tripped = _trip_row(p, spec, point, theta0_rad, str(m.get("end_reason")))
        tripped["group"] = group
        if out_dir is not None:
            tripped["run_dir"] = str(out_dir)
        return tripped, periods
    row: dict[str, Any] = {"group": group, "controller": spec.controller, "label": spec.label,
                           "ts_us": round(ts_s * 1e6, 3), "speed_rpm": cfg.scenario.speed_rpm,
                           "load_nm": cfg.scenario.load_nm, "theta0_rad": theta0_rad}
    for key in ROW_METRICS:
        row[key] = m.get(key)
    if p.evaluation is not None:
        row["eval_e"] = evaluation_e(row, *p.evaluation)
        row["eval_e_intra"] = evaluation_e(row, *p.evaluation, fav_key="switching_freq_intra_khz")
    split = m.get("exec_split_us")
    row["exec_time_us_median"] = (m.get("exec_time_us") or {}).get("median")
    row["exec_split_us_median"] = split.get("median") if isinstance(split, dict) else None
    row["t_reach_98pct_s"] = _reach_time(periods, cfg.scenario.speed_rpm)
    row["end_reason"] = m.get("end_reason")
    if out_dir is not None:
        row["run_dir"] = str(out_dir)
    return row, periods


def _trip_row(p: ComparePreset, spec: Variant, point: dict[str, float], theta0_rad: float,
              reason: str) -> dict[str, Any]:
    """Row of a run the plant's protection ended before the metrics window: no metrics, the reason."""
    overrides: dict[str, Any] = {"speed_rpm": p.speed_rpm, "load_nm": p.load_nm, **point}
    scenario = load_scenario(p.scenario).with_overrides(**overrides)
    row: dict[str, Any] = {"group": "main", "controller": spec.controller, "label": spec.label,
                           "ts_us": round(p.ts_s * 1e6, 3), "speed_rpm": scenario.speed_rpm,
                           "load_nm": scenario.load_nm, "theta0_rad": theta0_rad}
    row.update(dict.fromkeys(ROW_METRICS))
    row.update(exec_time_us_median=None, exec_split_us_median=None, t_reach_98pct_s=None, end_reason=reason)
    return row


def _points(p: ComparePreset) -> list[dict[str, float]]:
    if p.points:
        return [dict(pt) for pt in p.points]
    if p.sweep_key is None:
        return [{}]
    return [{p.sweep_key: v} for v in p.sweep_values]


def _spec(p: ComparePreset, label: str) -> Variant:
    return next((v for v in p.specs() if v.label == label), Variant(label, label))


@dataclass(frozen=True, slots=True)
class CompareTask:
    """One run of a preset as sent to an engine's worker (src/pmsm_hil/app/sweep/engines.py)."""

    preset: ComparePreset
    spec: Variant
    ts_s: float
    point: dict[str, float]
    group: str = "main"
    theta0_rad: float = 0.0
    out_dir: Path | None = None
    #: return the speed/torque series (the accel figure's run)
    series: bool = False
    #: `out_dir` made absolute in the coordinating process
    abs_out_dir: Path | None = None

    def __post_init__(self) -> None:
        if self.out_dir is not None and self.abs_out_dir is None:
            object.__setattr__(self, "abs_out_dir", Path(self.out_dir).absolute())


@dataclass(frozen=True, slots=True)
class TaskResult:
    """A run's row and (accel) series, or the plant-trip reason, or another error's message."""

    row: dict[str, Any] | None = None
    series: dict[str, list[float]] | None = None
    trip: str | None = None
    error: str | None = None


def run_task(task: CompareTask) -> TaskResult:
    """Run one task (in a worker): `run_one`, the accel series subsampled to ~3000 points. `out_dir` is
    made absolute by the caller (a worker's working directory may be another); the row names it as given."""
    try:
        row, periods = run_one(task.preset, task.spec, task.ts_s, task.point, group=task.group,
                               theta0_rad=task.theta0_rad, out_dir=task.abs_out_dir)
        if task.out_dir is not None:
            row["run_dir"] = str(task.out_dir)
    except HilError as exc:
        if "plant trip" in str(exc):
            return TaskResult(trip=str(exc))
        return TaskResult(error=str(exc))
    series = None
    if task.series:
        step = max(1, len(periods) // 3000)
        series = {"t": periods["t"][::step].tolist(),
                  "speed_rpm": (periods["omega_m"][::step] / RPM_TO_RAD_S).tolist(),
                  "torque_nm": periods["torque"][::step].tolist()}
    return TaskResult(row=row, series=series)


def _run_all(engine: Engine, tasks: list[CompareTask], say: Progress, labels: list[str]) -> list[TaskResult]:
    """Every task on the engine; results in task order; progress as they finish."""
    out: list[TaskResult | None] = [None] * len(tasks)
    for n, (i, res, error) in enumerate(engine.map_unordered(run_task, tasks), start=1):
        out[i] = res if error is None else TaskResult(error=f"worker lost: {error}")
        say(f"run {labels[i].rstrip()} ({n}/{len(tasks)})")
    return [r if r is not None else TaskResult(error="no result") for r in out]


def _equal_fav(p: ComparePreset, result: CompareResult, progress: Progress, engine: Engine,
               run_dir: RunDirFor | None = None) -> None:
    """Change the adjusted run's Ts until its f_av (`p.equal_fav_metric`, mean over the initial rotor
    angles) matches the reference's (f_av ∝ 1/Ts). Points search side by side: each round runs every
    rotor angle of every point still searching."""
    assert p.equal_fav is not None  # checked by the caller
    ref_name, adj_name = p.equal_fav
    key = p.equal_fav_metric
    adj = _spec(p, adj_name)
    searches: list[dict[str, Any]] = []
    for point in _points(p):
        refs = [r for r in result.rows if r.get("label", r["controller"]) == ref_name and r["group"] == "main"
                and all(r[k] == v for k, v in point.items()) and r.get(key)]
        if refs:
            searches.append({"point": point, "target": float(np.mean([float(r[key]) for r in refs])),
                             "ts": p.ts_s, "rows": [], "done": False})
    for _ in range(FAV_ITER):
        active = [s for s in searches if not s["done"]]
        if not active:
            break
        tasks = [CompareTask(p, adj, s["ts"], s["point"], "equal_fav", th,
                             run_dir(adj, s["point"], th, "equal_fav") if run_dir else None)
                 for s in active for th in p.theta0_rad]
        outcomes = iter(_run_all(engine, tasks, lambda _msg: None, [""] * len(tasks)))
        for s in active:
            s["rows"] = []
            for _th in p.theta0_rad:
                res = next(outcomes)
                if res.row is None:
                    raise HilError(f"{adj_name} equal f_av: {res.trip or res.error}")
                s["rows"].append(res.row)
            fav = float(np.mean([float(r[key] or 0.0) for r in s["rows"]]))
            ts, target = s["ts"], s["target"]
            progress(f"  equal f_av: {adj_name} at Ts = {ts * 1e6:.1f} µs -> {fav:.3f} kHz (target {target:.3f})")
            if fav <= 0.0 or abs(fav - target) <= FAV_TOL * target:
                s["done"] = True
                continue
            ts_new = round(ts * fav / target * 1e7) / 1e7  # f_av ∝ 1/Ts; 0.1 µs grid
            ts_new = min(max(ts_new, MIN_TS_S), MAX_TS_S)  # the run-option schema's --ts range
            if math.isclose(ts_new, ts):
                s["done"] = True
                continue
            s["ts"] = ts_new
    for s in searches:
        for row in s["rows"]:
            row["equal_fav_target_khz"] = s["target"]
            result.rows.append(row)


def run_preset(p: ComparePreset, *, controllers: list[str] | None = None,
               progress: Progress | None = None, run_dir: RunDirFor | None = None,
               engine: Engine | None = None) -> CompareResult:
    """Run every controller/variant at every operating point and initial rotor angle of the preset, then
    the equal-f_av search. `run_dir`: which runs to log, and where (rows of logged runs, tripped ones
    too, carry `run_dir`). `engine`: where the runs go (src/pmsm_hil/app/sweep/engines.py; default: this process, one
    after the other); rows come back in the same order on every engine."""
    say = progress or (lambda _msg: None)
    engine = engine or InlineEngine()
    result = CompareResult(p)
    specs = [s for s in p.specs() if controllers is None or s.controller in controllers or s.label in controllers]
    tasks: list[CompareTask] = []
    labels: list[str] = []
    for point in _points(p):
        for spec in specs:
            for theta0 in p.theta0_rad:
                label = ", ".join(f"{k}={v:g}" for k, v in point.items())
                if len(p.theta0_rad) > 1:
                    label = f"{label}, theta0={theta0:g}".lstrip(", ")
                out_dir = run_dir(spec, point, theta0, "main") if run_dir else None
                tasks.append(CompareTask(p, spec, p.ts_s, point, "main", theta0, out_dir,
                                         series=p.figure == "accel" and theta0 == p.theta0_rad[0]))
                labels.append(f"{spec.label} {label}")
    for task, label, res in zip(tasks, labels, _run_all(engine, tasks, say, labels), strict=True):
        if res.error is not None:
            raise HilError(f"{label.rstrip()}: {res.error}")
        if res.trip is not None:
            say(f"  {label.rstrip()}: {res.trip}")
            result.rows.append(_trip_row(p, task.spec, task.point, task.theta0_rad, res.trip))
            if task.out_dir is not None:
                result.rows[-1]["run_dir"] = str(task.out_dir)
            continue
        assert res.row is not None
        result.rows.append(res.row)
        if res.series is not None:
            result.series[task.spec.label] = res.series
    if p.equal_fav is not None:
        _equal_fav(p, result, say, engine, run_dir)
    return result
