"""The sweep plans of the sweep tests: short runs (0.06 s simulated), 16 runs for the engine comparison."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pmsm_hil.app.sweep.rows import deterministic_view

#: base `hil run` options of every test run: 0.06 s simulated (settling 0.03 s, window 0.03 s)
SHORT = ["--duration", "0.03", "--settle", "0.03"]
#: 2 controllers × 2 loads × 4 rotor angles = 16 runs
GRID16 = ["--grid", "controller=mpcc,dsvm-20", "--grid", "load=3,7", "--repeat", "4", *SHORT]


def results(out: Path) -> dict[str, dict[str, Any]]:
    """Rows of OUT/results.json by run id."""
    return {r["run_id"]: r for r in json.loads((out / "results.json").read_text(encoding="utf-8"))}


def deterministic(out: Path) -> dict[str, dict[str, Any]]:
    """Rows by run id without the wall-clock metrics and run facts."""
    return {rid: deterministic_view(row) for rid, row in results(out).items()}
