"""Compare presets: which controllers, at which operating points, against which paper figures."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from pmsm_hil.hil.errors import InputFileError, ParameterError
from pmsm_hil.hil.resources import bundled_names, load_toml

_PACKAGE = "pmsm_hil.app.compare.presets"
FIGURES = ("none", "bars", "thd_vs_load", "ripple_vs_speed", "accel")
SWEEP_KEYS = ("load_nm", "speed_rpm")
FAV_METRICS = ("switching_freq_khz", "switching_freq_intra_khz")


@dataclass(frozen=True, slots=True)
class Variant:
    """One run specification: a table label, the controller and its `--param` values (SI units)."""

    label: str
    controller: str
    params: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True, slots=True)
class ComparePreset:
    """One paper experiment. Speeds rpm, torques N·m, times s.

    sweep_key/sweep_values: operating points (None: the scenario's own point). equal_fav: (reference,
    adjusted) controllers: the adjusted one's control period is shortened until its average switching
    frequency matches the reference's. paper: label -> metric -> value from the paper's text. params:
    controller parameters of every run; variants: extra labelled runs (controller + params);
    points: explicit operating points (speed_rpm and/or load_nm each), instead of a one-key sweep;
    theta0_rad: initial rotor angles [rad, electrical], one run each (the table shows their mean, the
    JSON the spread); equal_fav_metric: the f_av figure matched (`switching_freq_khz` or
    `switching_freq_intra_khz`); evaluation: (torque base N·m, f_av base kHz) of eq. (12) of
    003_7bbad73a6f78337e.txt, E = ΔT_pp/T_b + f_av/f_b + THD/100.
    """

    name: str
    motor: str
    scenario: str
    controllers: tuple[str, ...]
    ts_s: float = 100e-6
    settle_s: float | None = None
    duration_s: float | None = None
    speed_rpm: float | None = None
    load_nm: float | None = None
    sweep_key: str | None = None
    sweep_values: tuple[float, ...] = ()
    points: tuple[dict[str, float], ...] = ()
    equal_fav: tuple[str, str] | None = None
    figure: str = "none"
    description: str = ""
    paper: dict[str, dict[str, float]] = field(default_factory=dict)
    paper_note: str = ""
    params: dict[str, float] = field(default_factory=dict)
    variants: tuple[Variant, ...] = ()
    theta0_rad: tuple[float, ...] = (0.0,)
    equal_fav_metric: str = "switching_freq_khz"
    evaluation: tuple[float, float] | None = None

    def specs(self) -> list[Variant]:
        """The runs at each operating point: the plain controllers, then the variants."""
        return [Variant(c, c) for c in self.controllers] + list(self.variants)


def preset_names() -> list[str]:
    """Bundled preset names."""
    return bundled_names(_PACKAGE)


def _num(doc: dict[str, Any], key: str, origin: str) -> float | None:
    value = doc.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputFileError(f"compare preset {origin}: '{key}' must be a finite number")
    return float(value)


def load_preset(name_or_path: str) -> ComparePreset:
    """Load a bundled preset by name or a TOML file; errors name the key."""
    doc, origin = load_toml(name_or_path, _PACKAGE, file_label="compare preset", kind="compare preset")
    known = {"name", "motor", "scenario", "controllers", "ts_s", "settle_s", "duration_s", "speed_rpm", "load_nm",
             "sweep", "equal_fav", "figure", "description", "paper", "paper_note", "params", "variants",
             "theta0_rad", "evaluation", "points"}
    unknown = set(doc) - known
    if unknown:
        raise InputFileError(f"compare preset {origin}: unknown key(s) {', '.join(sorted(unknown))}")
    for key in ("name", "motor", "scenario"):
        if not isinstance(doc.get(key), str):
            raise InputFileError(f"compare preset {origin}: '{key}' must be a string")
    ctrls = doc.get("controllers", [] if "variants" in doc else None)
    if not isinstance(ctrls, list) or not all(isinstance(c, str) for c in ctrls) or not (ctrls or "variants" in doc):
        raise InputFileError(f"compare preset {origin}: 'controllers' must be a non-empty list of names")
    params = _params(doc.get("params", {}), "params", origin)
    variants = _variants(doc.get("variants", []), origin)
    theta0 = doc.get("theta0_rad", [0.0])
    if (not isinstance(theta0, list) or not theta0
            or not all(isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in theta0)):
        raise InputFileError(f"compare preset {origin}: 'theta0_rad' must be a non-empty list of numbers")
    evaluation = None
    ev = doc.get("evaluation")
    if ev is not None:
        if not isinstance(ev, dict):
            raise InputFileError(f"compare preset {origin}: 'evaluation' needs torque_base_nm and fav_base_khz")
        tb, fb = _num(ev, "torque_base_nm", origin), _num(ev, "fav_base_khz", origin)
        if tb is None or fb is None or tb <= 0 or fb <= 0:
            raise InputFileError(f"compare preset {origin}: 'evaluation' needs positive torque_base_nm and "
                                 "fav_base_khz")
        evaluation = (tb, fb)
    figure = doc.get("figure", "none")
    if figure not in FIGURES:
        raise InputFileError(f"compare preset {origin}: 'figure' must be one of {', '.join(FIGURES)}")
    sweep_key: str | None = None
    sweep_values: tuple[float, ...] = ()
    sweep = doc.get("sweep")
    if sweep is not None:
        if not isinstance(sweep, dict) or sweep.get("key") not in SWEEP_KEYS:
            raise InputFileError(f"compare preset {origin}: 'sweep.key' must be one of {', '.join(SWEEP_KEYS)}")
        values = sweep.get("values")
        if (not isinstance(values, list) or not values
                or not all(isinstance(v, int | float) and math.isfinite(v) for v in values)):
            raise InputFileError(f"compare preset {origin}: 'sweep.values' must be a non-empty list of numbers")
        sweep_key, sweep_values = str(sweep["key"]), tuple(float(v) for v in values)
    points = _points(doc.get("points"), origin)
    if points and sweep_key is not None:
        raise InputFileError(f"compare preset {origin}: give either 'sweep' or 'points', not both")
    equal: tuple[str, str] | None = None
    fav_metric = "switching_freq_khz"
    eq = doc.get("equal_fav")
    if eq is not None:
        if not isinstance(eq, dict) or not isinstance(eq.get("reference"), str) or not isinstance(
                eq.get("adjust"), str):
            raise InputFileError(f"compare preset {origin}: 'equal_fav' needs string keys reference and adjust")
        equal = (eq["reference"], eq["adjust"])
        fav_metric = eq.get("metric", fav_metric)
        if fav_metric not in FAV_METRICS:
            raise InputFileError(f"compare preset {origin}: 'equal_fav.metric' must be one of {', '.join(FAV_METRICS)}")
    paper: dict[str, dict[str, float]] = {}
    for ctrl, vals in dict(doc.get("paper", {})).items():
        if not isinstance(vals, dict) or not all(isinstance(v, int | float) for v in vals.values()):
            raise InputFileError(f"compare preset {origin}: 'paper.{ctrl}' must map metric names to numbers")
        paper[str(ctrl)] = {str(k): float(v) for k, v in vals.items()}
    ts = _num(doc, "ts_s", origin)
    return ComparePreset(
        name=doc["name"], motor=doc["motor"], scenario=doc["scenario"], controllers=tuple(ctrls),
        ts_s=100e-6 if ts is None else ts, settle_s=_num(doc, "settle_s", origin),
        duration_s=_num(doc, "duration_s", origin), speed_rpm=_num(doc, "speed_rpm", origin),
        load_nm=_num(doc, "load_nm", origin), sweep_key=sweep_key, sweep_values=sweep_values, points=points,
        equal_fav=equal,
        figure=str(figure), description=str(doc.get("description", "")), paper=paper,
        paper_note=str(doc.get("paper_note", "")), params=params, variants=variants,
        theta0_rad=tuple(float(v) for v in theta0), equal_fav_metric=str(fav_metric), evaluation=evaluation)


def _points(value: object, origin: str) -> tuple[dict[str, float], ...]:
    """`points = [{ speed_rpm = ..., load_nm = ... }, ...]`: operating points (rpm, N·m)."""
    if value is None:
        return ()
    if not isinstance(value, list) or not value:
        raise InputFileError(f"compare preset {origin}: 'points' must be a non-empty list of tables")
    out: list[dict[str, float]] = []
    for k, item in enumerate(value):
        if not isinstance(item, dict) or not item or set(item) - set(SWEEP_KEYS):
            raise InputFileError(f"compare preset {origin}: 'points[{k}]' must set {' and/or '.join(SWEEP_KEYS)}")
        point: dict[str, float] = {}
        for key in SWEEP_KEYS:
            v = _num(item, key, f"{origin} points[{k}]")
            if v is not None:
                point[key] = v
        out.append(point)
    return tuple(out)


def _params(value: object, where: str, origin: str) -> dict[str, float]:
    """Controller parameters: numbers, or named values such as zero_select = "min_transitions"."""
    if not isinstance(value, dict):
        raise InputFileError(f"compare preset {origin}: '{where}' must map parameter names to values")
    from pmsm_hil.hil.runner.run_config import PARAM_VALUE_NAMES, param_id  # the runner: when a preset is read

    out: dict[str, float] = {}
    for name, v in value.items():
        names = PARAM_VALUE_NAMES.get(str(name), {})
        if isinstance(v, str) and v in names:
            out[str(name)] = names[v]
        elif isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v):
            out[str(name)] = float(v)
        else:
            raise InputFileError(f"compare preset {origin}: '{where}.{name}' must be a number"
                                 + (f" or one of {', '.join(names)}" if names else ""))
        try:
            param_id(str(name))
        except ParameterError as exc:
            raise InputFileError(f"compare preset {origin}: '{where}': {exc}") from None
    return out


def _variants(value: object, origin: str) -> tuple[Variant, ...]:
    """`[[variants]]` tables: label, controller, optional params."""
    if not isinstance(value, list):
        raise InputFileError(f"compare preset {origin}: 'variants' must be a list of tables")
    out: list[Variant] = []
    for k, item in enumerate(value):
        if (not isinstance(item, dict) or not isinstance(item.get("label"), str)
                or not isinstance(item.get("controller"), str)):
            raise InputFileError(f"compare preset {origin}: 'variants[{k}]' needs string keys label and controller")
        out.append(Variant(item["label"], item["controller"],
                           _params(item.get("params", {}), f"variants[{k}].params", origin)))
    return tuple(out)
