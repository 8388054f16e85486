"""Load motor presets (bundled names or TOML files) and apply ``--set`` overrides."""

from __future__ import annotations

from typing import Any

from pmsm_hil.hil.errors import InputFileError, ParameterError
from pmsm_hil.hil.motor_params import PmsmParams
from pmsm_hil.hil.resources import bundled_names, load_toml

_PRESET_PACKAGE = "pmsm_hil.hil.presets"


def preset_names() -> list[str]:
    """Names of the bundled motor presets."""
    return bundled_names(_PRESET_PACKAGE)


def load_motor(name_or_path: str, overrides: dict[str, float] | None = None) -> PmsmParams:
    """Load a bundled preset by name or a TOML file, then apply overrides (SI units)."""
    doc, origin = load_toml(name_or_path, _PRESET_PACKAGE, file_label="motor file", kind="motor preset")
    table = doc.get("parameters")
    if not isinstance(table, dict):
        raise InputFileError(f"motor file {origin}: missing [parameters] table")
    values: dict[str, Any] = {}
    for key, entry in table.items():
        value = entry.get("value") if isinstance(entry, dict) else entry
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise InputFileError(f"motor file {origin}: parameter '{key}' needs a numeric value")
        values[key] = value
    if "pole_pairs" in values:
        if float(values["pole_pairs"]) != int(values["pole_pairs"]):
            raise InputFileError(f"motor file {origin}: 'pole_pairs' must be an integer")
        values["pole_pairs"] = int(values["pole_pairs"])
    known = set(PmsmParams.__dataclass_fields__) - {"name"}
    unknown = set(values) - known
    if unknown:
        raise InputFileError(f"motor file {origin}: unknown parameter(s) {', '.join(sorted(unknown))}")
    missing = {"rs", "ld", "lq", "psi_f", "pole_pairs", "vdc", "j"} - set(values)
    if missing:
        raise InputFileError(f"motor file {origin}: missing parameter(s) {', '.join(sorted(missing))}")
    floats: dict[str, Any] = {k: (v if k == "pole_pairs" else float(v)) for k, v in values.items()}
    try:
        params = PmsmParams(name=str(doc.get("name", origin)), **floats)
    except ParameterError as exc:
        raise InputFileError(f"motor file {origin}: {exc}") from None
    return params.with_overrides(overrides) if overrides else params
