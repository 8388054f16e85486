"""`hil compare`: paper experiments as presets, run closed loop per controller, tables and figures.

The names below load on first use (`hil compare --help` lists the presets without importing the runner)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from pmsm_hil.lazy_names import lazy_getattr

if TYPE_CHECKING:
    from pmsm_hil.app.compare.preset import ComparePreset, load_preset, preset_names
    from pmsm_hil.app.compare.runs import CompareResult, run_preset

_LAZY = {
    **dict.fromkeys(("ComparePreset", "load_preset", "preset_names"), "pmsm_hil.app.compare.preset"),
    **dict.fromkeys(("CompareResult", "run_preset"), "pmsm_hil.app.compare.runs"),
}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())


__all__ = ["ComparePreset", "CompareResult", "load_preset", "preset_names", "run_preset"]
