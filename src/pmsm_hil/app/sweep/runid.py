"""Stable run ids: a hash of the canonical form of a run's configuration.

The canonical form is the validated RunConfig as JSON (every field, nested dataclasses as objects, keys
sorted, floats in their shortest exact text) without what only decides where and what is logged
(`out_dir`, `log_trace`, `trace_dt_s`) and without free text that does not change the run (the scenario's
description). Two runs with the same id simulate the same thing; a changed preset, scenario file or
option changes the id (a resumed sweep reruns it).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from typing import Any

from pmsm_hil.hil.runner.run_config import RunConfig

#: RunConfig fields that do not change what is simulated (or restate another: `link_spec` is `link` parsed)
_LOGGING_FIELDS = ("out_dir", "log_trace", "trace_dt_s", "link_spec")
#: hex digits of a run id (64 bits: collisions are negligible for any sweep that fits a disk)
ID_LENGTH = 16


def canonical_config(cfg: RunConfig) -> dict[str, Any]:
    """The configuration as plain JSON values (see the module docstring)."""
    doc = dataclasses.asdict(cfg)
    for name in _LOGGING_FIELDS:
        doc.pop(name, None)
    doc["scenario"].pop("description", None)
    return doc


def canonical_text(cfg: RunConfig) -> str:
    """`canonical_config` as compact JSON with sorted keys."""
    return json.dumps(canonical_config(cfg), sort_keys=True, separators=(",", ":"), default=str)


def run_id(cfg: RunConfig) -> str:
    """The run's id: the first ID_LENGTH hex digits of the SHA-256 of its canonical text."""
    return hashlib.sha256(canonical_text(cfg).encode("utf-8")).hexdigest()[:ID_LENGTH]


__all__ = ["ID_LENGTH", "canonical_config", "canonical_text", "run_id"]
