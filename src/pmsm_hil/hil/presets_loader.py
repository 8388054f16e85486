"""Load motor presets (bundled names or TOML files) and apply ``--set`` overrides."""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

from pmsm_hil.hil.errors import InputFileError, ParameterError
from pmsm_hil.hil.machine_params import MachineParams
from pmsm_hil.hil.motor_params import PmsmParams
from pmsm_hil.hil.resources import bundled_names, load_toml

_PRESET_PACKAGE = "pmsm_hil.hil.presets"
#: the machine kind of a preset without `kind` (a PMSM: three- or dual three-phase by its lls)
DEFAULT_KIND = "three-phase"


def preset_names() -> list[str]:
    """Names of the bundled motor presets."""
    return bundled_names(_PRESET_PACKAGE)


def load_motor(name_or_path: str, overrides: dict[str, float] | None = None) -> MachineParams:
    """Load a bundled preset by name or a TOML file, then apply overrides (SI units). The optional top-level
    `kind` names the machine kind (`pmsm_hil.hil.machine.LAYOUTS`; default: a PMSM, three- or dual three-phase
    by its lls) whose parameter class reads the `[parameters]` table. Returns that class's instance
    (`MachineParams`)."""
    from pmsm_hil.hil.machine import params_class_for_kind

    doc, origin = load_toml(name_or_path, _PRESET_PACKAGE, file_label="motor file", kind="motor preset")
    table = doc.get("parameters")
    if not isinstance(table, dict):
        raise InputFileError(f"motor file {origin}: missing [parameters] table")
    kind = doc.get("kind", DEFAULT_KIND)
    if not isinstance(kind, str):
        raise InputFileError(f"motor file {origin}: 'kind' must be a string, got {kind!r}")
    try:
        params_class = params_class_for_kind(kind)
    except ParameterError as exc:
        raise InputFileError(f"motor file {origin}: {exc}") from None
    values: dict[str, Any] = _file_keys(doc, origin, params_class)
    for key, entry in table.items():
        value = entry.get("value") if isinstance(entry, dict) else entry
        if not isinstance(value, (int, float)) or isinstance(value, bool):
            raise InputFileError(f"motor file {origin}: parameter '{key}' needs a numeric value")
        values[key] = value
    try:
        params: MachineParams = params_class.from_values(values, str(doc.get("name", origin)))
    except ParameterError as exc:
        raise InputFileError(f"motor file {origin}: {exc}") from None
    return params.with_overrides(overrides) if overrides else params


def _file_keys(doc: dict[str, Any], origin: str, params_class: Any) -> dict[str, Any]:
    """The top-level keys naming files next to the TOML (a kind's `FILE_KEYS`, e.g. a flux map), as paths: relative
    names are taken from the TOML's folder (a bundled preset's: the presets package)."""
    out: dict[str, Any] = {}
    for key in getattr(params_class, "FILE_KEYS", ()):
        if key not in doc:
            continue
        name = doc[key]
        if not isinstance(name, str) or not name:
            raise InputFileError(f"motor file {origin}: '{key}' must be a file name, got {name!r}")
        path = Path(name)
        if not path.is_absolute():
            origin_path = Path(origin)
            base = (origin_path.parent if origin_path.suffix == ".toml" or origin_path.exists()
                    else Path(str(resources.files(_PRESET_PACKAGE))))
            path = base / path
        out[key] = str(path.resolve())
    return out


def load_pmsm(name_or_path: str, overrides: dict[str, float] | None = None) -> PmsmParams:
    """`load_motor` for what only a PMSM has (benches against PMSM references): ParameterError naming the motor
    when its preset is another machine kind."""
    params = load_motor(name_or_path, overrides)
    if not isinstance(params, PmsmParams):
        raise ParameterError(f"--motor {name_or_path}: a {type(params).__name__} machine; this needs a PMSM")
    return params
