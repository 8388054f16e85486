"""Run options as data: `from_options(values, sources)` turns option values (by the keys of the run-option
schema, hil/runner/run_options.py) into a checked RunConfig — the one path of `hil run`, `hil sweep`, the pytest
plugin's `hil.run(...)` and the benches.

Values come in layers, later ones winning: the defaults (the schema's), a `--config` file, then overrides (the
command line, a sweep point, `hil.run` keyword arguments); `layer(...)` merges them and remembers each value's
source ("default", "config file PATH", "--option", "sweep grid key K", "plan file PATH key K",
"hil.run(K=...)", ...). A table option (`set`, `param`, `load_fmu_set`) is a dict of NAME → value (or
"NAME=VALUE" texts, or `KEY.NAME` items); a later layer's items go on top of an earlier one's, each item with its
own source (`set.rs`). A value may be the option's Python value or its command-line text (a sweep's grid value).
An error is one line naming the field and where its value came from: the option on the command line, the file and
key of a config file, the grid key of a sweep.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from pmsm_hil.hil.errors import InputFileError, ParameterError
from pmsm_hil.hil.load_fmu.spec import load_fmu_spec
from pmsm_hil.hil.motor_params import parse_set_options
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run_config import RunConfig, check_params_used, parse_param_options
from pmsm_hil.hil.runner.run_limits import check_run_limits
from pmsm_hil.hil.runner.run_options import BY_FIELD, DEFAULTS, OPTIONS, RunOption
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.hil.sensors import SensorConfig
from pmsm_hil.sim_target.fw_params import default_controller

from pmsm_hil.errors import HilError

#: the source of a value nobody set
DEFAULT = "default"
#: table options: their values are NAME → value items
TABLES = frozenset(o.key for o in OPTIONS.values() if o.kind == "table")
#: the scenario's fields the options --speed, --load, --duration, --settle, --hold-tolerance override
_SCENARIO_OVERRIDES = {"speed": "speed_rpm", "load": "load_nm", "duration": "duration_s", "settle": "settle_s",
                       "hold_tolerance": "hold_tolerance_pct"}

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


def _item_texts(table: Mapping[str, Any]) -> list[str]:
    return [f"{name}={value!r}" if isinstance(value, float) else f"{name}={value}" for name, value in table.items()]


class _Inputs:
    """Checked option values with their sources, read by key (a default where none is set)."""

    def __init__(self, values: Mapping[str, Any], sources: Mapping[str, str] | None) -> None:
        given = dict(sources or {})

        def where(key: str) -> str:  # an item's own source, else its table's, else the option (a library call)
            return given.get(key) or given.get(key.split(".", 1)[0]) or option_of(key).option

        merged, layered = layer((values, where))
        self.sources: Sources = layered
        self.values: Values = {}
        for key, value in merged.items():
            option = option_of(key)
            if option.kind == "table":
                self.values[key] = value
                continue
            with blame(key, self.sources):
                self.values[key] = coerce(option, value)

    def __call__(self, key: str) -> Any:
        return self.values.get(key, DEFAULTS[key])

    def given(self, key: str) -> bool:
        return key in self.values

    def table(self, key: str) -> dict[str, Any]:
        return dict(self.values.get(key, {}))


def from_options(values: Mapping[str, Any], sources: Mapping[str, str] | None = None) -> RunConfig:
    """The checked RunConfig of option `values` (see the module docstring); `sources` by key, "default" where a
    key is missing from `values`. ParameterError / InputFileError naming the field and its source."""
    get = _Inputs(values, sources)
    src = get.sources
    motor = _motor(get)
    with blame("scenario", src):
        scenario = load_scenario(str(get("scenario")))
    for key, name in _SCENARIO_OVERRIDES.items():
        with blame(key, src):
            scenario = scenario.with_overrides(**{name: get(key)})
    controller_params: dict[str, float] = {}
    for name, value in get.table("param").items():
        with blame(f"param.{name}", src):
            controller_params.update(parse_param_options(_item_texts({name: value})))
    with blame("load_fmu", src):
        load_fmu = load_fmu_spec(get("load_fmu"), get("load_fmu_map"), _item_texts(get.table("load_fmu_set")),
                                 isolation=get("load_fmu_isolation"))
    if load_fmu is not None and get.given("load"):
        raise ParameterError(f"{label('load', src)} and --load-fmu: one load at a time (the FMU replaces the "
                             "scenario's load torque)", key="load")
    fields: dict[str, Any] = {name: get(option.key) for name, option in BY_FIELD.items()}
    if not get.given("controller"):  # a user firmware (sil:/qemu:) runs as `external` unless one is named
        fields["controller"] = default_controller(str(fields["target"]), str(fields["controller"]))
    fields["faults"] = str(fields["faults"] or "")
    fields["log_trace"] = bool(fields["log_trace"])
    with blame("noise", src):
        sensors = SensorConfig(adc_lsb_a=float(get("adc_lsb")), noise_std_a=float(get("noise")),
                               encoder_counts=int(get("encoder_counts")), seed=int(get("seed")))
    try:
        with blame(None, src):
            cfg = RunConfig(motor=motor, scenario=scenario, controller_params=controller_params, sensors=sensors,
                            out_dir=_out_dir(get, str(fields["controller"])), load_fmu=load_fmu, **fields)
    except (TypeError, ValueError) as exc:
        if isinstance(exc, HilError):
            raise
        raise ParameterError(f"bad option value: {exc}") from None
    with blame("param", src):
        check_params_used(cfg.controller, cfg.controller_params)
    check_run_limits(cfg, speed_option=label("speed", src, f"scenario '{scenario.name}' speed_rpm"),
                     duration_option=label("duration", src, f"scenario '{scenario.name}' duration_s"))
    return cfg


def _motor(get: _Inputs) -> Any:
    """The motor preset or file with the `set` items on it, each item's error naming its source."""
    src = get.sources
    overrides: dict[str, float] = {}
    for name, value in get.table("set").items():
        with blame(f"set.{name}", src):
            overrides.update(parse_set_options(_item_texts({name: value})))
    with blame("motor", src):
        motor = load_motor(str(get("motor")))
    if not overrides:
        return motor
    try:
        return load_motor(str(get("motor")), overrides)
    except ParameterError:
        applied: dict[str, float] = {}
        for name, value in overrides.items():  # one at a time: the refused value names its own item
            applied[name] = value
            with blame(f"set.{name}", src):
                load_motor(str(get("motor")), dict(applied))
        raise


def _out_dir(get: _Inputs, controller: str) -> Path | None:
    """None with `no_log`; `out`; else a fresh `runs/<time>-<controller>`."""
    if get("no_log"):
        return None
    out = get("out")
    return Path(out) if out is not None else fresh_dir(Path("runs") / f"{time.strftime('%Y%m%d-%H%M%S')}-{controller}")


def fresh_dir(base: Path) -> Path:
    """`base`, or `base-2`, `base-3`, ... if a run of the same second already took it."""
    path, n = base, 2
    while path.exists():
        path, n = base.with_name(f"{base.name}-{n}"), n + 1
    return path


__all__ = ["DEFAULT", "TABLES", "Sources", "Values", "blame", "coerce", "fresh_dir", "from_options", "label",
           "layer", "locate", "option_of", "source_of"]
