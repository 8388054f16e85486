"""Bundled TOML files (motor presets, scenarios, compare presets): list them, load one by name or path."""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Any

import tomllib
from pmsm_hil.hil.errors import InputFileError, ParameterError


def bundled_names(package: str) -> list[str]:
    """Sorted names (without `.toml`) of the TOML files bundled in `package`."""
    root = resources.files(package)
    return sorted(p.name.removesuffix(".toml") for p in root.iterdir() if p.name.endswith(".toml"))


def load_toml(name_or_path: str, package: str, *, file_label: str, kind: str) -> tuple[dict[str, Any], str]:
    """Parse a TOML file (a path ending in `.toml` or an existing path) or the bundled `<name>.toml` of
    `package`; return (document, origin), origin being the path or the name.

    InputFileError "<file_label> <origin>: ..." if the file cannot be read or parsed; ParameterError
    "unknown <kind> '<name>' (bundled: ...)" for an unknown bundled name."""
    path = Path(name_or_path)
    if path.suffix == ".toml" or path.exists():
        try:
            text, origin = path.read_text(encoding="utf-8"), str(path)
        except OSError as exc:
            raise InputFileError(f"{file_label} {path}: {exc.strerror}") from None
    else:
        res = resources.files(package) / f"{name_or_path}.toml"
        if not res.is_file():
            raise ParameterError(f"unknown {kind} '{name_or_path}' (bundled: {', '.join(bundled_names(package))})")
        text, origin = res.read_text(encoding="utf-8"), name_or_path
    try:
        return tomllib.loads(text), origin
    except tomllib.TOMLDecodeError as exc:
        raise InputFileError(f"{file_label} {origin}: {exc}") from None
