"""A sweep plan: which `hil run` choices vary, and the list of points they make.

A point is an ordered tuple of (key, text) pairs. Keys are the `hil run` config-file keys (`controller`,
`load`, `speed`, `duration`, `ts`, `motor`, `scenario`, `seed`, `noise`, `fault`, ...: the option's long name
without dashes, `-` as `_`), `set.NAME` (a `--set NAME=VALUE` plant parameter), `param.NAME` (a `--param`
controller parameter), `load_fmu_set.NAME` (a `--load-fmu-set` load-FMU parameter); `theta0` is `--theta0`, the initial
electrical rotor angle [rad]. Texts are what the option would receive on the command line; their meaning is
checked later by the `hil run` parser itself (src/pmsm_hil/app/sweep/configure.py), so a bad value gets the option's own
error.

Sources, crossed with each other in this order: the `runs` of a plan file (TOML `[[runs]]` tables, or the
rows of a CSV plan), the `[grid]` table of a TOML plan, then the `--grid KEY=V1,V2` options (the last
key varies fastest). `--repeat N` repeats every point over N initial rotor angles (src/pmsm_hil/app/sweep/configure.py).
"""

from __future__ import annotations

import csv
import io
import itertools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pmsm_hil.app.cli.config_file import read_toml
from pmsm_hil.hil.errors import InputFileError, ParameterError
from pmsm_hil.hil.runner.run_options import RUN_OPTIONS

Point = tuple[tuple[str, str], ...]

#: `hil run` options that are outputs or per-run files, never swept (the sweep owns its outputs)
OUTPUT_KEYS = frozenset({*(o.key for o in RUN_OPTIONS if o.scope == "output"), "config"})
#: key prefixes for `--set NAME=VALUE`, `--param NAME=VALUE` and `--load-fmu-set NAME=VALUE` (a load FMU's parameter)
TABLE_PREFIXES = tuple(f"{o.key}." for o in RUN_OPTIONS if o.kind == "table" and o.scope == "run")
#: the initial electrical rotor angle [rad] (the scenario's `theta0_rad`)
THETA0 = "theta0"


def sweep_keys() -> list[str]:
    """Every key a grid or plan may set (the `hil run` config-file keys but outputs)."""
    from pmsm_hil.app.cli.run import config_schema

    keys = [k for k, spec in config_schema().items() if k not in OUTPUT_KEYS and spec.kind != "table"]
    return [*keys, *(f"{prefix}NAME" for prefix in TABLE_PREFIXES)]


def check_key(key: str, where: str) -> str:
    """`key` stripped if a sweep may set it; ParameterError "<where>: unknown key ..." if not."""
    from pmsm_hil.app.cli.run import config_schema

    key = key.strip()
    if key.startswith(TABLE_PREFIXES) and key.split(".", 1)[1].strip():
        return key
    spec = config_schema().get(key)
    if spec is None or key in OUTPUT_KEYS or spec.kind == "table":
        why = "is an output or file of the sweep itself" if key in OUTPUT_KEYS else "is unknown"
        if key in ("set", "param"):
            why = f"needs a name: {key}.NAME"
        raise ParameterError(f"{where}: key '{key}' {why} (keys: {', '.join(sweep_keys())})")
    return key


def split_values(text: str) -> list[str]:
    """`V1,V2,...` (or `V1;V2` when a value itself holds commas, e.g. a --fault SPEC) as stripped texts."""
    sep = ";" if ";" in text else ","
    return [v.strip() for v in text.split(sep)]


def parse_grid(items: Sequence[str]) -> list[tuple[str, list[str]]]:
    """`--grid KEY=V1,V2` options as (key, values) in order; errors name the option and the key."""
    grid: list[tuple[str, list[str]]] = []
    seen: set[str] = set()
    for item in items:
        key, sep, text = item.partition("=")
        if not sep or not key.strip():
            raise ParameterError(f"--grid expects KEY=V1,V2,..., got {item!r}")
        key = check_key(key, "--grid")
        values = split_values(text)
        if not all(values):
            raise ParameterError(f"--grid {key}: empty value in {text!r}")
        if key in seen:
            raise ParameterError(f"--grid {key}: given twice (list every value in one --grid)")
        seen.add(key)
        grid.append((key, values))
    return grid


def _text(value: Any, where: str) -> str:
    """A TOML value as the option's text: numbers exactly (repr), strings as they are."""
    if isinstance(value, bool) or not isinstance(value, int | float | str):
        raise InputFileError(f"{where} must be a number or a string, got {value!r}")
    if isinstance(value, float):
        if not math.isfinite(value):
            raise InputFileError(f"{where} must be finite, got {value!r}")
        return repr(value)
    return str(value)


@dataclass(frozen=True, slots=True)
class PlanFile:
    """What a plan file gives: explicit runs (each a point), a grid, a repeat count (None: not given)."""

    runs: tuple[Point, ...] = ()
    grid: tuple[tuple[str, tuple[str, ...]], ...] = ()
    repeat: int | None = None


def load_plan(path: Path) -> PlanFile:
    """A TOML plan (`[grid]` KEY = [values], `[[runs]]` tables of KEY = value, `repeat = N`) or a CSV plan
    (a header of keys, one run per row, an empty cell leaves the key unset). Errors name the file, the
    row and the key."""
    if path.suffix.lower() == ".csv":
        return _load_csv(path)
    doc = read_toml(path, "plan file")
    where = f"plan file {path}"
    unknown = set(doc) - {"grid", "runs", "repeat"}
    if unknown:
        raise InputFileError(f"{where}: unknown key(s) {', '.join(sorted(unknown))} (known: grid, runs, repeat)")
    repeat = doc.get("repeat")
    if repeat is not None and (isinstance(repeat, bool) or not isinstance(repeat, int) or repeat < 1):
        raise InputFileError(f"{where}: 'repeat' must be a whole number ≥ 1, got {repeat!r}")
    grid_doc = _flatten_tables(doc.get("grid", {}), where, "grid")
    grid: list[tuple[str, tuple[str, ...]]] = []
    for key, values in grid_doc.items():
        name = _file_key(key, f"{where}: grid")
        if not isinstance(values, list) or not values:
            raise InputFileError(f"{where}: grid.{key} must be a non-empty list of values")
        grid.append((name, tuple(_text(v, f"{where}: grid.{key}[{k}]") for k, v in enumerate(values))))
    runs_doc = doc.get("runs", [])
    if not isinstance(runs_doc, list) or not all(isinstance(r, dict) for r in runs_doc):
        raise InputFileError(f"{where}: 'runs' must be a list of tables ([[runs]])")
    runs: list[Point] = []
    for k, run in enumerate(runs_doc):
        flat = _flatten_tables(run, where, f"runs[{k}]")
        runs.append(tuple((_file_key(key, f"{where}: runs[{k}]"), _text(v, f"{where}: runs[{k}].{key}"))
                          for key, v in flat.items()))
    if not grid and not runs:
        raise InputFileError(f"{where}: no runs (give a [grid] table or [[runs]] tables)")
    return PlanFile(tuple(runs), tuple(grid), repeat)


def _flatten_tables(value: object, where: str, name: str) -> dict[str, Any]:
    """`{set = {rs = [..]}}` (a TOML `[grid.set]` table) as `{"set.rs": [..]}`; dotted keys kept."""
    if not isinstance(value, dict):
        raise InputFileError(f"{where}: '{name}' must be a table")
    out: dict[str, Any] = {}
    for key, v in value.items():
        if key in ("set", "param") and isinstance(v, dict):
            for sub, w in v.items():
                out[f"{key}.{sub}"] = w
        else:
            out[str(key)] = v
    return out


def _file_key(key: str, where: str) -> str:
    try:
        return check_key(key, where)
    except ParameterError as exc:
        raise InputFileError(str(exc)) from None


def _load_csv(path: Path) -> PlanFile:
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        why = exc.strerror if isinstance(exc, OSError) else "not UTF-8 text"
        raise InputFileError(f"plan file {path}: {why}") from None
    rows = list(csv.reader(io.StringIO(text)))
    rows = [r for r in rows if any(c.strip() for c in r)]
    if len(rows) < 2:
        raise InputFileError(f"plan file {path}: needs a header of keys and at least one run row")
    header = [_file_key(k, f"plan file {path}: header") for k in rows[0]]
    if len(set(header)) != len(header):
        raise InputFileError(f"plan file {path}: a key appears twice in the header")
    runs: list[Point] = []
    for n, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise InputFileError(f"plan file {path} row {n}: {len(row)} cells, the header has {len(header)}")
        runs.append(tuple((k, c.strip()) for k, c in zip(header, row, strict=True) if c.strip()))
    return PlanFile(runs=tuple(runs))


def expand(runs: Iterable[Point], grids: Iterable[tuple[str, Sequence[str]]]) -> list[Point]:
    """Every listed run crossed with every grid point (the last grid key fastest); a key set by both is an
    error naming it."""
    grid = list(grids)
    base = list(runs) or [()]
    keys = [k for k, _ in grid]
    if len(set(keys)) != len(keys):
        dup = next(k for k in keys if keys.count(k) > 1)
        raise ParameterError(f"--grid {dup}: set by the plan file's grid and by --grid")
    points: list[Point] = []
    for run in base:
        clash = {k for k, _ in run} & set(keys)
        if clash:
            raise ParameterError(f"--grid {sorted(clash)[0]}: also set by a run of the plan file")
        for combo in itertools.product(*(values for _, values in grid)):
            points.append((*run, *zip(keys, combo, strict=True)))
    return points


def swept_keys(points: Sequence[Point]) -> list[str]:
    """Keys whose text differs between points, in first-seen order."""
    order: list[str] = []
    values: dict[str, set[str | None]] = {}
    for point in points:
        for key, _ in point:
            if key not in values:
                order.append(key)
                values[key] = set()
    for point in points:
        d = dict(point)
        for key in order:
            values[key].add(d.get(key))
    return [k for k in order if len(values[k]) > 1]


__all__ = [
    "THETA0",
    "PlanFile",
    "Point",
    "check_key",
    "expand",
    "load_plan",
    "parse_grid",
    "split_values",
    "sweep_keys",
    "swept_keys",
]
