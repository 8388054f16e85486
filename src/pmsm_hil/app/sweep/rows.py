"""Result rows: a run's metrics flattened to one level, and the columns that are wall-clock measurements.

Every metric of metrics.json becomes a column: a dict-valued key is flattened with dots
(`exec_time_us.median`, `link.frames_tx`, `dut_violations_by_rule.missing`), a list (warnings, the DUT
violation list) becomes its JSON text. Rows of one sweep are made column-compatible for Parquet/CSV by
`normalize`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from typing import Any, Final

#: Metrics measured with a clock on the machine that ran the loop (wall time, loop rate, the controller's
#: execution time, waits and lateness): they differ from run to run and between engines and worker counts.
#: Every other metric of a lockstep run is a pure function of the configuration and is bit-identical on
#: every engine (tests/sweep/test_engines.py). Keys are metrics.json keys; their sub-keys are included.
WALL_CLOCK_METRICS: Final = ("wall_time_s", "loop_rate_hz", "total_wall_time_s", "loop_rate_total_hz",
                             "command_wait_max_us", "exec_time_us", "exec_split_us", "exec_time_first_us",
                             "lateness_us", "lateness_histogram_us", "overruns", "deadline_misses", "late_periods",
                             "missed_periods", "safe_stop_wait_ms")
#: Columns a sweep adds about where and how long a run ran (not metrics, not compared)
RUN_FACTS: Final = ("host", "pid", "blas_threads", "run_wall_s", "mcap")


def is_wall_clock(column: str) -> bool:
    """True for a column of a wall-clock metric (or one of its sub-keys) or a run fact."""
    head = column.split(".", 1)[0]
    return head in WALL_CLOCK_METRICS or column in RUN_FACTS


def flatten(metrics: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """`{"a": {"b": 1}, "c": [..]}` → `{"a.b": 1, "c": "[..]"}` (non-finite floats as None)."""
    out: dict[str, Any] = {}
    for key, value in metrics.items():
        name = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flatten(value, f"{name}."))
        elif isinstance(value, list | tuple):
            out[name] = json.dumps(value, separators=(",", ":"), default=str)
        elif isinstance(value, float) and not math.isfinite(value):
            out[name] = None
        else:
            out[name] = value
    return out


def deterministic_view(row: Mapping[str, Any]) -> dict[str, Any]:
    """The row without wall-clock metrics and run facts (what every engine gives bit-identically)."""
    return {k: v for k, v in row.items() if not is_wall_clock(k)}


def columns(rows: Iterable[Mapping[str, Any]]) -> list[str]:
    """Every column of the rows in first-seen order."""
    seen: dict[str, None] = {}
    for row in rows:
        for key in row:
            seen.setdefault(key, None)
    return list(seen)


def normalize(rows: Sequence[Mapping[str, Any]]) -> tuple[list[str], list[dict[str, Any]]]:
    """Columns and rows with one type per column: numbers with any float as float, booleans, else text
    (a column that mixes kinds becomes text). Missing cells are None."""
    cols = columns(rows)
    kinds: dict[str, set[str]] = {c: set() for c in cols}
    for row in rows:
        for c in cols:
            v = row.get(c)
            if v is None:
                continue
            kinds[c].add("bool" if isinstance(v, bool) else "int" if isinstance(v, int)
                         else "float" if isinstance(v, float) else "text")
    out: list[dict[str, Any]] = []
    for row in rows:
        new: dict[str, Any] = {}
        for c in cols:
            v = row.get(c)
            k = kinds[c]
            if v is None:
                new[c] = None
            elif k <= {"int", "float"} and "float" in k:
                new[c] = float(v)
            elif len(k) > 1:
                new[c] = v if isinstance(v, str) else json.dumps(v)
            else:
                new[c] = v
        out.append(new)
    return cols, out


__all__ = ["RUN_FACTS", "WALL_CLOCK_METRICS", "columns", "deterministic_view", "flatten", "is_wall_clock",
           "normalize"]
