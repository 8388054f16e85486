"""`hil compare`: paper experiments as presets, run closed loop per controller, tables and figures.

The names below load on first use (`hil compare --help` lists the presets without importing the runner)."""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from pmsm_hil.app.compare.preset import ComparePreset, load_preset, preset_names
    from pmsm_hil.app.compare.runs import CompareResult, run_preset

_LAZY = {
    **dict.fromkeys(("ComparePreset", "load_preset", "preset_names"), "pmsm_hil.app.compare.preset"),
    **dict.fromkeys(("CompareResult", "run_preset"), "pmsm_hil.app.compare.runs"),
}


def __getattr__(name: str) -> Any:
    """Load a compare name on first use."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


__all__ = ["ComparePreset", "CompareResult", "load_preset", "preset_names", "run_preset"]
