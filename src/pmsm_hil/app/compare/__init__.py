"""`hil compare`: paper experiments as presets, run closed loop per controller, tables and figures."""

from pmsm_hil.app.compare.preset import ComparePreset, load_preset, preset_names
from pmsm_hil.app.compare.runs import CompareResult, run_preset

__all__ = ["ComparePreset", "CompareResult", "load_preset", "preset_names", "run_preset"]
