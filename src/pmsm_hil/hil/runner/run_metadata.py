"""What a run log records about the run's set-up: the configuration as MCAP metadata (`/run/metadata`,
enough to repeat the run) and the ConfigParam/ConfigAck frames of the configuration (`/frames`).

Plain keys (read by the replay, the HTML report and Foxglove): motor, controller, scenario, ts_s, link,
mode, seed, speed_rpm, load_nm, pole_pairs, phases. JSON-valued keys: `motor_params` (every motor and
inverter parameter as run, `--set` applied), `motor_set` (the parameters that differ from the named preset,
i.e. the `--set` overrides), `controller_params` (`--param`), `target_parameters` (every ConfigParam
written, by name), `scenario_params` (every scenario field, CLI overrides applied), `sensors`; and `target`,
`miss_policy`, `watchdog_periods`, `log_trace`, `pwm_update` (the carrier of duty-cycle Commands, read by the
replay), `version` (the pmsm-hil package version); `load_fmu` (JSON, the
load FMU as metrics.json says it) when the load is an FMU."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from pmsm_hil.dist_version import installed_version
from pmsm_hil.hil.drive_params import flat_values
from pmsm_hil.hil.errors import HilError
from pmsm_hil.hil.machine_params import MachineParams
from pmsm_hil.hil.runner.recorder import FrameTap, frame_records
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.target_client import TargetClient
from pmsm_hil.protocol.links.spec import redact_spec

#: the files a run writes into its output directory (`RunConfig.out_dir`)
RUN_FILES = ("run.mcap", "metrics.json")


def package_version() -> str:
    """Installed pmsm-hil version ('unknown' when run from a tree that is not installed)."""
    return installed_version("pmsm-hil", "unknown")


def _params_dict(motor: MachineParams) -> dict[str, Any]:
    """The motor's parameter dataclass as a flat dict (the drive's fields beside the machine's)."""
    if not dataclasses.is_dataclass(motor) or isinstance(motor, type):
        raise TypeError(f"{type(motor).__name__}: a machine's parameter class must be a dataclass")
    return flat_values(motor)


def _motor_set(motor: MachineParams) -> dict[str, Any] | None:
    """Parameters that differ from the preset or file the motor is named after (None if it cannot be loaded)."""
    from pmsm_hil.hil.presets_loader import load_motor

    try:
        base = load_motor(motor.name)
    except (HilError, OSError):
        return None
    if type(base) is not type(motor) or not dataclasses.is_dataclass(motor):
        return None
    values, base_values = flat_values(motor), flat_values(base)
    return {k: v for k, v in values.items() if k != "name" and v != base_values[k]}


def _json(value: Any) -> str:
    return json.dumps(value, sort_keys=True, default=str)


def run_metadata(cfg: RunConfig) -> dict[str, str]:
    """Metadata mapping (str → str) of a run (see the module docstring)."""
    sc, m = cfg.scenario, cfg.motor
    meta = {"motor": m.name, "controller": cfg.controller, "scenario": sc.name, "ts_s": repr(cfg.ts_s),
            "link": redact_spec(cfg.link), "mode": cfg.mode, "seed": str(cfg.seed), "speed_rpm": repr(sc.speed_rpm),
            "load_nm": repr(sc.load_nm), "pole_pairs": str(m.pole_pairs), "phases": str(cfg.machine.phases),
            "target": cfg.target, "miss_policy": cfg.miss_policy, "watchdog_periods": str(cfg.watchdog_periods),
            "log_trace": "true" if cfg.log_trace else "false", "pwm_update": cfg.pwm_update,
            "version": package_version(),
            "motor_params": _json(_params_dict(m)),
            "controller_params": _json(cfg.controller_params),
            "target_parameters": _json({p.name.lower(): v for p, v in cfg.target_parameters().items()}),
            "scenario_params": _json(dataclasses.asdict(sc)),
            "sensors": _json(dataclasses.asdict(cfg.sensors))}
    motor_set = _motor_set(m)
    if motor_set is not None:
        meta["motor_set"] = _json(motor_set)
    fmu = cfg.load_fmu_model
    if fmu is not None:  # the load FMU that ran, as metrics.json `load_fmu`
        meta["load_fmu"] = _json(fmu.as_metrics())
    return meta


@contextmanager
def tap_setup_frames(client: TargetClient, logger: Any) -> Iterator[None]:
    """Record the frames exchanged inside the block (the ConfigParam writes and their ConfigAcks, t = 0,
    seq 0: before the first period) and submit them to `logger`'s `/frames`; no-op without a logger.
    The loop taps the link itself from its first Setpoint on."""
    if logger is None:
        yield
        return
    link = client.link
    tap = FrameTap(link, frame_records())
    client.link = tap
    try:
        yield
    finally:
        client.link = link
        if len(tap.records):
            logger.submit_frames(tap.records.take())
