"""Sweep points as run configurations, through `hil run`'s own parser and `config_from_args`.

Each point becomes the command-line options it stands for (`load=3` → `--load=3`, `set.rs=4.5` →
`--set=rs=4.5`), parsed by a parser holding exactly `hil run`'s run options on top of the sweep's own
options (the base of every run), then merged with defaults and `--config` by `config_from_args`. So every
value is checked by the option's own parser and message: a bad grid value is a one-line ParameterError
naming the key (`--grid load: --load must be a number, got 'x'`).

Repeats: `--repeat N` gives run k (0..N-1) the initial electrical rotor angle theta0 + 2πk/N (theta0: the
point's, else the scenario's `theta0_rad`) and the seed seed + k (seed: the point's `--seed`, else the base
one, default 0), so every repeat of every controller sees the same angles and noise sequences.
"""

from __future__ import annotations

import argparse
import copy
import functools
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, NoReturn

from pmsm_hil.app.cli.parsing import finite_float
from pmsm_hil.app.sweep.plan import TABLE_PREFIXES, THETA0, Point
from pmsm_hil.app.sweep.runid import run_id
from pmsm_hil.hil.errors import HilError, ParameterError
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.run_options import RUN_OPTIONS


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


class _RaisingParser(argparse.ArgumentParser):
    """argparse that raises ParameterError instead of exiting (a bad grid value is a one-line error)."""

    def error(self, message: str) -> NoReturn:
        raise ParameterError(message)


@functools.cache
def _run_parser() -> argparse.ArgumentParser:
    from pmsm_hil.app.cli.run import add_run_arguments

    p = _RaisingParser(prog="hil sweep", add_help=False)
    add_run_arguments(p)
    return p


def base_args(argv: Sequence[str] = ()) -> argparse.Namespace:
    """Base options of every run from `hil run` option strings (e.g. ["--duration", "0.1"])."""
    try:
        return _run_parser().parse_args(list(argv))
    except ParameterError as exc:
        raise ParameterError(str(exc).removeprefix("argument ")) from None


def point_argv(point: Point) -> list[str]:
    """The `hil run` options a point stands for (theta0 excluded: the scenario's angle, set separately)."""
    from pmsm_hil.app.cli.run import config_schema

    argv: list[str] = []
    for key, text in point:
        if key == THETA0:
            continue
        prefix = next((p for p in TABLE_PREFIXES if key.startswith(p)), None)
        if prefix is not None:
            argv.append(f"--{prefix[:-1].replace('_', '-')}={key[len(prefix):]}={text}")
        else:
            argv.append(f"{config_schema()[key].option}={text}")
    return argv


def _option_of(key: str) -> str:
    from pmsm_hil.app.cli.run import config_schema

    if key.startswith(TABLE_PREFIXES):
        return "--" + key.split(".", 1)[0].replace("_", "-")
    spec = config_schema().get(key)
    return spec.option if spec is not None else key


def _grid_error(message: str, point: Point, where: str) -> ParameterError:
    """'<where> <key>: <message>' naming the key whose option the message is about, else the point."""
    text = message.removeprefix("argument ")
    for key, _ in point:
        option = _option_of(key)
        if text.startswith(f"{option}: ") or text.startswith(f"{option}/"):
            return ParameterError(f"{where} {key}: {text.split(': ', 1)[1]}")
        if option in text or f"'{key}'" in text:
            return ParameterError(f"{where} {key}: {text}")
    for key, value in point:  # a configuration error quoting the value or the name (unknown controller 'x')
        name = key.split(".", 1)[1] if key.startswith(TABLE_PREFIXES) else None
        if f"'{value}'" in text or (name is not None and f"'{name}'" in text):
            return ParameterError(f"{where} {key}: {text}")
    shown = ", ".join(f"{k}={v}" for k, v in point) or "(base options)"
    return ParameterError(f"{where} {shown}: {text}")


def build_config(base: argparse.Namespace, point: Point, *, where: str = "--grid") -> RunConfig:
    """The validated RunConfig of one point over the base options (the sweep's run options)."""
    from pmsm_hil.app.cli.run import config_from_args

    ns = copy.copy(base)
    for option in RUN_OPTIONS:  # the tables (--set, --param, --load-fmu-set): the point's items on top of the base's
        if option.kind == "table":
            setattr(ns, option.target, list(getattr(base, option.target, []) or []))
    try:
        args = _run_parser().parse_args(point_argv(point), namespace=ns)
    except ParameterError as exc:
        raise _grid_error(str(exc), point, where) from None
    args.no_log, args.out, args.json, args.overwrite = True, None, None, None
    try:
        cfg = config_from_args(args)
    except HilError as exc:
        raise _grid_error(str(exc), point, where) from None
    theta = dict(point).get(THETA0)
    if theta is not None:
        try:
            angle = finite_float(THETA0)(theta)
        except argparse.ArgumentTypeError as exc:
            raise ParameterError(f"{where} {THETA0}: {exc}") from None
        cfg = replace(cfg, scenario=cfg.scenario.with_overrides(theta0_rad=angle))
    return cfg


def with_repeat(cfg: RunConfig, k: int, n: int) -> RunConfig:
    """Repeat k of n: rotor angle advanced by 2πk/n [rad, electrical], seed + k (noise and faults)."""
    if n <= 1:
        return cfg
    seed = cfg.seed + k
    return replace(cfg, seed=seed, sensors=replace(cfg.sensors, seed=seed),
                   scenario=cfg.scenario.with_overrides(theta0_rad=cfg.scenario.theta0_rad + 2.0 * math.pi * k / n))


def build_runs(base: argparse.Namespace, points: Sequence[Point], repeat: int, *,
               where: str = "--grid") -> list[SweepRun]:
    """Every point × repeat as a SweepRun (all validated before anything runs); duplicate configurations
    (two points that resolve to the same run) are kept once."""
    runs: list[SweepRun] = []
    seen: set[str] = set()
    for point in points:
        cfg = build_config(base, point, where=where)
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


__all__ = ["SweepRun", "base_args", "build_config", "build_runs", "config_text", "point_argv", "store_dir",
           "with_repeat"]
