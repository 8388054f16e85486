"""Bundled TOML files (motor presets, scenarios, compare presets): list them, load one by name or path."""

from __future__ import annotations

import tomllib
from importlib import resources
from pathlib import Path
from typing import Any

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
            data, origin = path.read_bytes(), str(path)
        except OSError as exc:
            raise InputFileError(f"{file_label} {path}: {exc.strerror}") from None
    else:
        res = resources.files(package) / f"{name_or_path}.toml"
        if not res.is_file():
            raise ParameterError(f"unknown {kind} '{name_or_path}' (bundled: {', '.join(bundled_names(package))})")
        data, origin = res.read_bytes(), name_or_path
    return parse_toml_bytes(data, f"{file_label} {origin}"), origin


def parse_toml_bytes(data: bytes, where: str) -> dict[str, Any]:
    """Parse TOML bytes; InputFileError "<where>: ..." naming the first non-UTF-8 byte or the syntax error."""
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise InputFileError(f"{where}: not UTF-8 text (byte 0x{data[exc.start]:02x} on line {line}); "
                             "save the file as UTF-8") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputFileError(f"{where}: {exc}") from None
