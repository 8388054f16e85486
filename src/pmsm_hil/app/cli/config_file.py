"""`--config FILE.toml`: option values from a TOML file, checked against the command's own argparse options.

The schema is derived from the parser (one source): a key is an option's long name without the dashes and
with underscores (`--miss-policy` → `miss_policy`, `--set` → `[set]` table). Each value must have the
option's type as a TOML value — numbers as TOML numbers (run through the option's own range check), flags
as TOML booleans (`true`/`false`, never the strings "yes" or "false"), choices and names as strings,
`--set`/`--param` as tables of NAME = number. Errors name the file and the key in one line.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pmsm_hil.hil.errors import InputFileError
from pmsm_hil.hil.resources import parse_toml_bytes


@dataclass(frozen=True, slots=True)
class ConfigKey:
    """One key of a config file: the option it mirrors and how its value is checked."""

    key: str
    option: str
    dest: str
    kind: str  # "flag" | "choice" | "text" | "path" | "number" | "table"
    parse: Callable[[str], Any] | None = None
    choices: tuple[str, ...] = ()
    #: a --param table also takes named values (strings), e.g. zero_select = "min_transitions"
    table_text: bool = False


def schema_from_parser(parser: argparse.ArgumentParser, *, exclude: Iterable[str] = ()) -> dict[str, ConfigKey]:
    """Config keys of every long option of `parser` except `exclude` (dest names) and --help."""
    skip = {"help", *exclude}
    schema: dict[str, ConfigKey] = {}
    for action in parser._actions:
        longs = [o for o in action.option_strings if o.startswith("--")]
        if not longs or action.dest in skip:
            continue
        option = longs[0]
        key = option[2:].replace("-", "_")
        if isinstance(action, argparse._StoreTrueAction | argparse._StoreFalseAction):
            schema[key] = ConfigKey(key, option, action.dest, "flag")
        elif isinstance(action, argparse._AppendAction):
            schema[key] = ConfigKey(key, option, action.dest, "table", table_text=key == "param")
        elif action.choices is not None:
            schema[key] = ConfigKey(key, option, action.dest, "choice",
                                    choices=tuple(str(c) for c in action.choices))
        elif action.type is None or action.type is str:
            schema[key] = ConfigKey(key, option, action.dest, "text")
        elif action.type is Path:
            schema[key] = ConfigKey(key, option, action.dest, "path")
        else:
            schema[key] = ConfigKey(key, option, action.dest, "number", parse=action.type)  # type: ignore[arg-type]
    return schema


def _is_number(value: object) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _number_text(value: int | float) -> str:
    return repr(value) if isinstance(value, int) or math.isfinite(value) else str(value)


def check_value(spec: ConfigKey, value: object, where: str) -> Any:
    """The value of `spec.key` as the option would hold it; InputFileError "<where>: '<key>' ..." if not."""
    name = f"{where}: '{spec.key}'"
    if spec.kind == "flag":
        if not isinstance(value, bool):
            raise InputFileError(f"{name} must be a TOML boolean (true or false, no quotes), got {value!r}")
        return value
    if spec.kind == "table":
        if not isinstance(value, dict):
            raise InputFileError(f"{name} must be a table of NAME = value, e.g. [{spec.key}]")
        items: list[str] = []
        for k, v in value.items():
            if _is_number(v) or (spec.table_text and isinstance(v, str)):
                items.append(f"{k}={_number_text(v) if _is_number(v) else v}")
            else:
                raise InputFileError(f"{where}: '{spec.key}.{k}' must be a number, got {v!r}")
        return items
    if spec.kind == "number":
        if not _is_number(value):
            raise InputFileError(f"{name} must be a number (no quotes), got {value!r}")
        assert spec.parse is not None
        try:
            return spec.parse(_number_text(value))  # type: ignore[arg-type]
        except argparse.ArgumentTypeError as exc:
            raise InputFileError(f"{where}: {str(exc).replace(spec.option, repr(spec.key), 1)}") from None
    if not isinstance(value, str):
        raise InputFileError(f"{name} must be a string, got {value!r}")
    if spec.kind == "choice" and value not in spec.choices:
        raise InputFileError(f"{name} must be one of {', '.join(spec.choices)}, got {value!r}")
    return Path(value) if spec.kind == "path" else value


def read_toml(path: Path, label: str) -> dict[str, Any]:
    """Parse a TOML file; InputFileError "<label> <path>: ..." if it cannot be read, is not UTF-8 or not TOML."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise InputFileError(f"{label} {path}: {exc.strerror}") from None
    return parse_toml_bytes(data, f"{label} {path}")


def load_config(path: Path, schema: dict[str, ConfigKey]) -> dict[str, Any]:
    """Checked values of a config file by key (tables as lists of "NAME=VALUE" strings, like the options)."""
    doc = read_toml(path, "config file")
    where = f"config file {path}"
    unknown = set(doc) - set(schema)
    if unknown:
        raise InputFileError(f"{where}: unknown key(s) {', '.join(sorted(unknown))} "
                             f"(known: {', '.join(sorted(schema))})")
    return {key: check_value(schema[key], value, where) for key, value in doc.items()}


__all__ = ["ConfigKey", "check_value", "load_config", "read_toml", "schema_from_parser"]
