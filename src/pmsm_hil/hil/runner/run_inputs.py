"""Run options as data: `from_options(values, sources)` turns option values (by the keys of the run-option
schema, src/pmsm_hil/hil/runner/run_options.py) into a checked RunConfig — the one path of `hil run`, `hil sweep`, the
pytest plugin's `hil.run(...)` and the benches. Layers, sources and coercion: src/pmsm_hil/hil/runner/option_values.py.

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
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from pmsm_hil.hil.errors import HilError, ParameterError
from pmsm_hil.hil.load_fmu.spec import load_fmu_spec
from pmsm_hil.hil.motor_params import parse_set_options
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.option_values import Sources, Values, blame, coerce, label, layer, option_of
from pmsm_hil.hil.runner.run_config import RunConfig, check_params_used, parse_param_options
from pmsm_hil.hil.runner.run_limits import check_run_limits
from pmsm_hil.hil.runner.run_options import BY_FIELD, DEFAULTS
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.hil.sensors import SensorConfig
from pmsm_hil.sim_target.fw_params import default_controller

#: the scenario's fields the options --speed, --load, --duration, --settle, --theta0, --hold-tolerance override
_SCENARIO_OVERRIDES = {"speed": "speed_rpm", "load": "load_nm", "duration": "duration_s", "settle": "settle_s",
                       "theta0": "theta0_rad", "hold_tolerance": "hold_tolerance_pct",
                       "load_inertia": "load_inertia_kgm2", "shaft_stiffness": "shaft_stiffness_nm_per_rad",
                       "shaft_damping": "shaft_damping_nms_per_rad", "shaft": "shaft"}
#: the options of a two-mass shaft (refused with a rigid one)
_SHAFT_OPTIONS = ("load_inertia", "shaft_stiffness", "shaft_damping")


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
    for key in _SHAFT_OPTIONS:
        if get.given(key) and scenario.shaft != "two-mass":
            raise ParameterError(f"{label(key, src)} is for a two-mass shaft (--shaft two-mass, or the scenario's "
                                 f"shaft = \"two-mass\"); scenario '{scenario.name}' has a {scenario.shaft} shaft",
                                 key=key)
    controller_params: dict[str, float] = {}
    for name, value in get.table("param").items():
        with blame(f"param.{name}", src):
            controller_params.update(parse_param_options(_item_texts({name: value})))
    with blame("load_fmu", src):
        load_fmu = load_fmu_spec(get("load_fmu"), get("load_fmu_map"), _item_texts(get.table("load_fmu_set")),
                                 isolation=get("load_fmu_isolation"))
    if load_fmu is not None and scenario.shaft == "two-mass":
        raise ParameterError(f"{label('load_fmu', src)} with a two-mass shaft: the load FMU drives a rigid shaft only",
                             key="load_fmu")
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


__all__ = ["fresh_dir", "from_options"]
