"""Compare presets: which controllers, at which operating points, against which paper figures."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import tomllib
from pmsm_hil.hil.errors import InputFileError, ParameterError

_PACKAGE = "pmsm_hil.hil.compare.presets"
FIGURES = ("none", "bars", "thd_vs_load", "ripple_vs_speed", "accel")
SWEEP_KEYS = ("load_nm", "speed_rpm")


@dataclass(frozen=True, slots=True)
class ComparePreset:
    """One paper experiment. Speeds rpm, torques N·m, times s.

    sweep_key/sweep_values: operating points (None: the scenario's own point). equal_fav: (reference,
    adjusted) controllers: the adjusted one's control period is shortened until its average switching
    frequency matches the reference's. paper: controller -> metric -> value from the paper's text.
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
    equal_fav: tuple[str, str] | None = None
    figure: str = "none"
    description: str = ""
    paper: dict[str, dict[str, float]] = field(default_factory=dict)
    paper_note: str = ""


def preset_names() -> list[str]:
    """Bundled preset names."""
    root = resources.files(_PACKAGE)
    return sorted(p.name.removesuffix(".toml") for p in root.iterdir() if p.name.endswith(".toml"))


def _read(name_or_path: str) -> tuple[str, str]:
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        try:
            return path.read_text(encoding="utf-8"), str(path)
        except OSError as exc:
            raise InputFileError(f"compare preset {path}: {exc.strerror}") from None
    res = resources.files(_PACKAGE) / f"{name_or_path}.toml"
    if not res.is_file():
        raise ParameterError(f"unknown compare preset '{name_or_path}' (bundled: {', '.join(preset_names())})")
    return res.read_text(encoding="utf-8"), name_or_path


def _num(doc: dict[str, Any], key: str, origin: str) -> float | None:
    value = doc.get(key)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputFileError(f"compare preset {origin}: '{key}' must be a finite number")
    return float(value)


def load_preset(name_or_path: str) -> ComparePreset:
    """Load a bundled preset by name or a TOML file; errors name the key."""
    text, origin = _read(name_or_path)
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputFileError(f"compare preset {origin}: {exc}") from None
    known = {"name", "motor", "scenario", "controllers", "ts_s", "settle_s", "duration_s", "speed_rpm", "load_nm",
             "sweep", "equal_fav", "figure", "description", "paper", "paper_note"}
    unknown = set(doc) - known
    if unknown:
        raise InputFileError(f"compare preset {origin}: unknown key(s) {', '.join(sorted(unknown))}")
    for key in ("name", "motor", "scenario"):
        if not isinstance(doc.get(key), str):
            raise InputFileError(f"compare preset {origin}: '{key}' must be a string")
    ctrls = doc.get("controllers")
    if not isinstance(ctrls, list) or not ctrls or not all(isinstance(c, str) for c in ctrls):
        raise InputFileError(f"compare preset {origin}: 'controllers' must be a non-empty list of names")
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
    equal: tuple[str, str] | None = None
    eq = doc.get("equal_fav")
    if eq is not None:
        if not isinstance(eq, dict) or not isinstance(eq.get("reference"), str) or not isinstance(
                eq.get("adjust"), str):
            raise InputFileError(f"compare preset {origin}: 'equal_fav' needs string keys reference and adjust")
        equal = (eq["reference"], eq["adjust"])
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
        load_nm=_num(doc, "load_nm", origin), sweep_key=sweep_key, sweep_values=sweep_values, equal_fav=equal,
        figure=str(figure), description=str(doc.get("description", "")), paper=paper,
        paper_note=str(doc.get("paper_note", "")))
