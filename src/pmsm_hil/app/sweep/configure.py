"""Sweep points as run configurations, through `RunConfig.from_options` (the path of every run).

Each point's values (`load=3`, `set.rs=4.5`: the texts of the grid or plan) go on top of the sweep's base options
(defaults < `--config` < the sweep's command line), each remembered as "sweep grid key K" (or "plan file PATH key
K"). So every value is checked by its option's own check, and an error names the key through that source, not by
reading the message: `--grid load: --load must be a number, got 'x'`.

Repeats: `--repeat N` gives run k (0..N-1) the initial electrical rotor angle theta0 + 2πk/N (theta0: the
point's, else the scenario's `theta0_rad`) and the seed seed + k (seed: the point's `--seed`, else the base
one, default 0), so every repeat of every controller sees the same angles and noise sequences.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from pmsm_hil.app.sweep.plan import THETA0, Point
from pmsm_hil.app.sweep.runid import run_id
from pmsm_hil.hil.runner.option_values import layer, option_of, source_of
from pmsm_hil.hil.runner.run_config import RunConfig


@dataclass(frozen=True, slots=True)
class SweepRun:
    """One run of a sweep: its id, its point (key → text, with `repeat`), and the validated configuration
    (`out_dir` None; the engine's task sets it when the run is logged)."""

    run_id: str
    point: Point
    repeat: int
    cfg: RunConfig

    def columns(self) -> dict[str, Any]:
        """The run's configuration columns: every point key (numbers as numbers), repeat, seed, theta0."""
        out: dict[str, Any] = {key: _value(text) for key, text in self.point}
        out["repeat"] = self.repeat
        out["seed"] = self.cfg.seed
        out[THETA0] = self.cfg.scenario.theta0_rad
        return out

    def label(self) -> str:
        """`controller=mpcc load=3 repeat=1` (the point and the repeat)."""
        return " ".join([*(f"{k}={v}" for k, v in self.point), f"repeat={self.repeat}"])


def _value(text: str) -> Any:
    try:
        value = float(text)
    except ValueError:
        return text
    return value if math.isfinite(value) else text


#: a sweep's base options: run-option values and their sources (`layer`, src/pmsm_hil/hil/runner/run_inputs.py)
BaseOptions = tuple[dict[str, Any], dict[str, str]]
#: what a sweep owns: its runs are never logged by `out`, and `hil run`'s after-run outputs do not apply
_SWEEP_OWNED = ("out", "no_log", "json", "overwrite", "expect_hold")


def base_options(values: Mapping[str, Any] | None = None, source: str | Callable[[str], str] = "--option"
                 ) -> BaseOptions:
    """The base options of every run of a sweep from run-option values by key (e.g. {"duration": 0.1}); `source`
    names where they came from (default: the command line's option of each)."""
    where = (lambda key: option_of(key).option) if source == "--option" else source
    return layer((dict(values or {}), where))


def point_source(key: str, plan: Path | None = None) -> str:
    """The source of a point's value: "sweep grid key K", or "plan file PATH key K"."""
    return f"plan file {plan} key {key}" if plan is not None else f"sweep grid key {key}"


def build_config(base: BaseOptions, point: Point, *, plan: Path | None = None) -> RunConfig:
    """The validated RunConfig of one point over the base options (the sweep's run options); an error names the
    point's key (`--grid load: --load must be a number, got 'x'`) or the base option, through the values' sources."""
    values, sources = layer(
        (base[0], lambda key: source_of(key, base[1])),
        (dict(point), lambda key: point_source(key, plan)))
    for key in _SWEEP_OWNED:
        values.pop(key, None)
    values["no_log"] = True
    return RunConfig.from_options(values, sources)


def with_repeat(cfg: RunConfig, k: int, n: int) -> RunConfig:
    """Repeat k of n: rotor angle advanced by 2πk/n [rad, electrical], seed + k (noise and faults)."""
    if n <= 1:
        return cfg
    seed = cfg.seed + k
    return replace(cfg, seed=seed, sensors=replace(cfg.sensors, seed=seed),
                   scenario=cfg.scenario.with_overrides(theta0_rad=cfg.scenario.theta0_rad + 2.0 * math.pi * k / n))


def build_runs(base: BaseOptions, points: Sequence[Point], repeat: int, *,
               plan: Path | None = None) -> list[SweepRun]:
    """Every point × repeat as a SweepRun (all validated before anything runs); duplicate configurations
    (two points that resolve to the same run) are kept once."""
    runs: list[SweepRun] = []
    seen: set[str] = set()
    for point in points:
        cfg = build_config(base, point, plan=plan)
        for k in range(repeat):
            rcfg = with_repeat(cfg, k, repeat)
            rid = run_id(rcfg)
            if rid not in seen:
                seen.add(rid)
                runs.append(SweepRun(rid, point, k, rcfg))
    return runs


def config_text(point: Point) -> str:
    """The point as a compact JSON object (the `config` column)."""
    return json.dumps(dict(point), separators=(",", ":"))


def store_dir(store: Path, rid: str) -> Path:
    """Where a logged run keeps run.mcap and metrics.json: STORE/<run id>."""
    return store / rid


__all__ = ["BaseOptions", "SweepRun", "base_options", "build_config", "build_runs", "config_text", "point_source",
           "store_dir", "with_repeat"]
