"""Run-option values with their sources: layers of values by key (defaults < a config file < overrides), where
each value came from ("default", "config file PATH", "--option", "sweep grid key K", "plan file PATH key K",
"hil.run(K=...)", ...), each value coerced to what its option holds, and errors that name the field by its source.
`RunConfig.from_options` (src/pmsm_hil/hil/runner/run_inputs.py) builds a run from them."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from pmsm_hil.hil.errors import InputFileError, ParameterError
from pmsm_hil.hil.runner.run_options import OPTIONS, RunOption

#: the source of a value nobody set
DEFAULT = "default"

Values = dict[str, Any]
Sources = dict[str, str]


def option_of(key: str) -> RunOption:
    """The option of a key (`set.rs` → `set`); ParameterError naming an unknown key and the known ones."""
    option = OPTIONS.get(key.split(".", 1)[0] if "." in key else key)
    if option is None or ("." in key and option.kind != "table"):
        raise ParameterError(f"unknown run option '{key}' (known: {', '.join(OPTIONS)})", key=key)
    return option


def _table_items(key: str, value: Any) -> dict[str, Any]:
    """A table option's value as NAME → value: a dict, "NAME=VALUE" texts, or one such text."""
    if isinstance(value, Mapping):
        return {str(k).strip(): v for k, v in value.items()}
    texts = [value] if isinstance(value, str) else list(value) if isinstance(value, Iterable) else None
    if texts is None or not all(isinstance(t, str) for t in texts):
        raise ParameterError(f"{OPTIONS[key].option} takes NAME=VALUE items (a table), got {value!r}", key=key)
    items: dict[str, Any] = {}
    for text in texts:
        name, sep, item = text.partition("=")
        if not sep or not name.strip():
            raise ParameterError(f"{OPTIONS[key].option} expects NAME=VALUE, got {text!r}", key=key)
        items[name.strip()] = item.strip()
    return items


def layer(*layers: tuple[Mapping[str, Any], str | Callable[[str], str]]) -> tuple[Values, Sources]:
    """Option values and their sources from `layers` (values by key, and the source of all of them or a function
    of the key giving it), later layers winning; a table's items merge, each keeping its source. None values
    (and empty tables) are not set."""
    values: Values = {}
    sources: Sources = {}
    for layer_values, source in layers:
        def where(key: str, source: str | Callable[[str], str] = source) -> str:
            return source if isinstance(source, str) else source(key)

        for key, value in layer_values.items():
            option = option_of(key)
            if value is None:
                continue
            if option.kind != "table":
                values[key], sources[key] = value, where(key)
                continue
            name = key.split(".", 1)[1] if "." in key else None
            items = {name: value} if name is not None else _table_items(option.key, value)
            table = values.setdefault(option.key, {})
            for item, item_value in items.items():
                table[item] = item_value
                sources[f"{option.key}.{item}"] = where(key if name is not None else f"{option.key}.{item}")
    return values, sources


def source_of(key: str, sources: Mapping[str, str]) -> str:
    """Where the value of `key` (or a table item `KEY.NAME`) came from."""
    if key in sources:
        return sources[key]
    return sources.get(key.split(".", 1)[0], DEFAULT) if "." in key else DEFAULT


def label(key: str, sources: Mapping[str, str], fallback: str | None = None) -> str:
    """How an error names the field `key` by its source: `--load`, `config file c.toml: 'load'`, `--grid load`,
    `plan file p.toml: load`, `hil.run(load=...)`, `--load (SOURCE)` for another source, else `fallback` (default:
    the option) for a default value."""
    source = source_of(key, sources)
    option = option_of(key).option + (f" {key.split('.', 1)[1]}" if "." in key else "")
    if source.startswith("config file "):
        return f"{source}: '{key}'"
    if source.startswith("sweep grid key "):
        return f"--grid {source.removeprefix('sweep grid key ')}"
    if source.startswith("plan file ") and " key " in source:
        path, _, grid_key = source.removeprefix("plan file ").rpartition(" key ")
        return f"plan file {path}: {grid_key}"
    if source == DEFAULT:
        return fallback or option
    if source.startswith(("--", "hil.run(")):
        return source
    return f"{option} ({source})"


def locate(message: str, key: str, sources: Mapping[str, str]) -> str:
    """`message` (an error about `key`) naming where the value came from: as it is when it came from the command
    line; a config file's key in place of the option; a sweep's grid key (or plan file and key) before it; a
    default named as such."""
    option = option_of(key).option
    source = source_of(key, sources)
    if source.startswith("config file "):
        named = message.replace(option, f"'{key}'", 1)
        return f"{source}: {named}" if named != message else f"{source}: '{key}': {message}"
    if source.startswith(("sweep grid key ", "plan file ")):
        return f"{label(key, sources)}: {message}"
    if source == DEFAULT:
        return f"{message} (the default {option})" if option not in message else message
    if source.startswith("--"):
        return message if source in message or option in message else f"{source}: {message}"
    return f"{source}: {message}"


@contextmanager
def blame(key: str | None, sources: Mapping[str, str]) -> Iterator[None]:
    """A ParameterError inside the block is about `key`, or about the key the error names itself (`exc.key`, which
    wins): re-raised naming where that value came from (`locate`), the key kept on it (unchanged without either).
    An InputFileError (a motor, scenario or FMU file names itself) gets the sweep key or file source before it."""
    try:
        yield
    except ParameterError as exc:
        named = exc.key if exc.key is not None and _known(exc.key) else key
        if named is None:
            raise
        raise ParameterError(locate(str(exc), named, sources), key=named) from None
    except InputFileError as exc:
        source = source_of(key, sources) if key is not None else DEFAULT
        if key is None or source == DEFAULT or source.startswith("--"):
            raise
        raise InputFileError(f"{label(key, sources)}: {exc}") from None


def _known(key: str) -> bool:
    try:
        option_of(key)
    except ParameterError:
        return False
    return True


def coerce(option: RunOption, value: Any) -> Any:
    """`value` (the option's Python value, or its command-line text) as the option holds it, checked; a table:
    NAME → value as given. ParameterError naming the option."""
    kind = option.kind
    if isinstance(value, str) and kind in ("number", "integer", "frequency"):
        return option.parse(value)
    if kind in ("number", "frequency"):
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise ParameterError(f"{option.option} must be a number, got {value!r}", key=option.key)
        return option.check(float(value))
    if kind == "integer":
        if isinstance(value, bool) or not isinstance(value, int | float) or float(value) != int(value):
            raise ParameterError(f"{option.option} must be an integer, got {value!r}", key=option.key)
        return option.check(int(value))
    if kind == "flag":
        if isinstance(value, str) and value.strip().lower() in ("true", "false"):
            return value.strip().lower() == "true"
        if not isinstance(value, bool):
            raise ParameterError(f"{option.option} is a flag: true or false, got {value!r}", key=option.key)
        return value
    if kind == "path":
        if not isinstance(value, str | Path):
            raise ParameterError(f"{option.option} must be a path, got {value!r}", key=option.key)
        return Path(value)
    if kind == "table":
        return _table_items(option.key, value)
    if isinstance(value, Path):
        value = str(value)
    if not isinstance(value, str):
        raise ParameterError(f"{option.option} must be a string, got {value!r}", key=option.key)
    return option.check(value)


__all__ = ["DEFAULT", "Sources", "Values", "blame", "coerce", "label", "layer", "locate", "option_of", "source_of"]
