"""A run replayed through the plant from its log (`hil replay RUN.mcap --output OUT.csv`, or a CAN log of it with
`--run-log RUN.mcap`): the run's set-up from the log's metadata (machine, Ts, the scenario's mechanics, load
profile and start state: angle, speed, load; the duty-cycle carrier), its Commands from `/frames` (or the capture)
applied as the loop applied them (`pmsm_hil.hil.replay_commands`), and the replayed currents compared with the
currents the run logged in `/periods`."""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np

from pmsm_hil.hil.atomic_write import refuse_inputs
from pmsm_hil.hil.drive_params import flat_values
from pmsm_hil.hil.errors import HilError, InputFileError
from pmsm_hil.hil.machine import LAYOUTS, Machine, load_machine, machine_for
from pmsm_hil.hil.machine_params import MachineParams
from pmsm_hil.hil.mechanics import DynoMechanics, InertiaMechanics, LoadProfile
from pmsm_hil.hil.pwm import PWM_UPDATES
from pmsm_hil.hil.replay import ReplayResult, plant_rows, write_rows
from pmsm_hil.hil.replay_canlog import read_log_commands
from pmsm_hil.hil.replay_commands import applied_periods
from pmsm_hil.hil.runlog.errors import McapFormatError
from pmsm_hil.hil.runlog.reader import ScanState, read_frames, read_metadata, read_periods
from pmsm_hil.hil.runner.loop_config import reference_changes
from pmsm_hil.hil.runner.scenario import Scenario
from pmsm_hil.protocol.codec import FrameDecoder
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.messages import Command

#: the phase currents of a period record compared with the replay, by phase count
CURRENTS = {3: ("i_a", "i_b", "i_c"), 6: ("i_a", "i_b", "i_c", "i_u", "i_v", "i_w")}


@dataclass(frozen=True, slots=True)
class RunReplay:
    """A replay of a logged run: its counts, and the largest |replayed − logged| phase current [A] over the
    `compared` periods the run logged (NaN when it logged none)."""

    result: ReplayResult
    compared: int
    max_error_a: float


def _scenario(meta: dict[str, str], where: str) -> Scenario:
    try:
        raw: dict[str, Any] = json.loads(meta["scenario_params"])
        names = {f.name for f in fields(Scenario)}
        values = {k: v for k, v in raw.items() if k in names}
        values["load_steps"] = tuple(tuple(p) for p in values.get("load_steps", ()))
        values["rated"] = tuple(values.get("rated", ()))
        return Scenario(**values)
    except KeyError:
        raise InputFileError(f"{where}: its metadata has no scenario_params (not a run log of `hil run`)") from None
    except (ValueError, TypeError, HilError) as exc:
        raise InputFileError(f"{where}: metadata scenario_params is not a scenario: {exc}") from None


def _built_from(values: dict[str, Any]) -> MachineParams | None:
    """The parameters of the kind whose parameter names are exactly the keys of `values`, or None."""
    for lay in LAYOUTS.values():
        cls: Any = lay.params_class
        if hasattr(cls, "parameter_names") and cls.parameter_names() | {"name"} == set(values):
            try:
                params: MachineParams = cls.build(**values)
                return params
            except (TypeError, HilError):
                continue
    return None


def _differences(params: MachineParams, logged: dict[str, Any]) -> list[str]:
    have = flat_values(params)
    return [k for k in sorted(logged) if k != "name"
            and json.dumps(have.get(k), default=str) != json.dumps(logged[k], default=str)]


def run_machine(meta: dict[str, str], where: str) -> Machine:
    """The machine the run ran: its motor preset with the run's `--set` overrides, checked against every parameter
    it logged (`motor_params`); or, where the preset is unknown here, built from the logged parameters."""
    try:
        logged: dict[str, Any] = json.loads(meta["motor_params"])
    except KeyError:
        raise InputFileError(f"{where}: its metadata has no motor_params; give --motor (and --set)") from None
    except ValueError as exc:
        raise InputFileError(f"{where}: metadata motor_params is not JSON: {exc}") from None
    overrides = json.loads(meta.get("motor_set", "{}") or "{}")
    try:
        machine = load_machine(meta.get("motor", ""), overrides)
        if not _differences(machine.params, logged):
            return machine
    except (HilError, OSError, TypeError):
        pass
    params = _built_from(dict(logged))
    if params is None or _differences(params, logged):
        raise InputFileError(f"{where}: the run's motor {meta.get('motor')!r} cannot be rebuilt here from its logged "
                             "parameters; give --motor (and --set)")
    return machine_for(params)


def _float(meta: dict[str, str], key: str, where: str) -> float:
    try:
        value = float(meta[key])
    except KeyError:
        raise InputFileError(f"{where}: its metadata has no {key} (not a run log of `hil run`)") from None
    except ValueError:
        raise InputFileError(f"{where}: metadata {key} {meta[key]!r} is not a number") from None
    if not (math.isfinite(value) and value > 0.0):
        raise InputFileError(f"{where}: metadata {key} {meta[key]!r} is not > 0")
    return value


def _mcap_commands(frames: np.ndarray) -> Iterable[Command]:
    decoder = FrameDecoder(ordered=False)
    for fr in frames:
        if int(fr["direction"]) != 1:
            continue
        msg = decoder.feed(Frame(int(fr["arbitration_id"]), bytes(fr["data"][:int(fr["length"])]), bool(fr["is_fd"])))
        if isinstance(msg, Command):
            yield msg


def replay_run(run_log: Path, output: Path, *, capture: Path | None = None, motor: MachineParams | None = None,
               allow_gaps: bool = False) -> RunReplay:
    """Replay the run logged in `run_log` (an MCAP of `hil run`) through the plant and write the replay CSV `output`.

    The Commands are the log's `/frames` (host-received), or those of the CAN log `capture` (a capture of the same
    run: it must begin with the run's first Command, seq 0). `motor` replaces the run's motor (default: rebuilt from
    the log). The loop's miss policy stands in for the Commands the run did not apply (its records' `missed`);
    a Command missing from the capture is an InputFileError naming its seq unless `allow_gaps`. Runs whose load is
    an FMU replay the load torque each period logged (held over the period, as the loop held the FMU's output)."""
    where = f"RUN.mcap {run_log}"
    inputs = [run_log] if capture is None else [run_log, capture]
    refuse_inputs(output, inputs, option="--output")
    state = ScanState()
    periods = read_periods(run_log, state)
    if not state.complete:
        raise McapFormatError(f"{where}: {state.cut_reason(run_log, 'replay')}")
    meta = read_metadata(run_log)
    ts_s = _float(meta, "ts_s", where)
    scenario = _scenario(meta, where)
    machine = run_machine(meta, where) if motor is None else machine_for(motor)
    layout = machine.layout
    pwm_update = meta.get("pwm_update", "single")
    if pwm_update not in PWM_UPDATES:
        raise InputFileError(f"{where}: metadata pwm_update {pwm_update!r} is not one of {', '.join(PWM_UPDATES)}")
    fmu_load = "load_fmu" in meta
    mech = scenario.plant_mechanics(machine.params.j)
    plant = machine.build_plant(ts_s, mech, theta0_rad=scenario.theta0_rad, trace_dt_s=None)
    if capture is None:
        commands: Iterable[Command] = _mcap_commands(read_frames(run_log))
        source = f"{where}: "
    else:
        commands = read_log_commands(capture)
        source = f"CAN log {capture}: "
    missed = np.flatnonzero(periods["missed"]) if len(periods) else np.array([], dtype=np.int64)
    applied = applied_periods(commands, ts_ns=plant.ts_ns, layout=layout, source=source, pwm_update=pwm_update,
                              allow_gaps=allow_gaps, first_seq=0, run_misses=(int(k) for k in missed),
                              miss_policy=meta.get("miss_policy", "zero"))
    if not applied.commands:
        raise InputFileError(f"{source}no Command frames (nothing to replay)")
    sequences = applied.sequences
    speed_at = dict(reference_changes(scenario, ts_s, len(sequences))) if scenario.mechanics == "dyno" else {}
    loads = periods["load_torque"] if fmu_load and len(periods) else None

    def before_period(k: int) -> None:
        """The loop's doings at the start of period k besides the sample: a new held speed, an FMU's torque."""
        if k in speed_at and k > 0:
            plant.mechanics = DynoMechanics(speed_at[k])
        if loads is not None and k < len(loads):
            plant.mechanics = InertiaMechanics(LoadProfile.constant(float(loads[k])))

    rows = plant_rows(plant, layout, sequences, before_period=before_period)
    write_rows(output, layout, rows)
    compared = min(len(periods), len(rows))
    if compared == 0:
        max_error = math.nan
    else:
        names = CURRENTS[layout.legs]  # the replay columns after t: the phase currents in this order
        replayed = np.array([row[1:1 + len(names)] for row in rows[:compared]])
        logged = np.column_stack([periods[n][:compared] for n in names])
        max_error = float(np.max(np.abs(replayed - logged)))
    return RunReplay(ReplayResult(len(sequences), applied.commands, applied.gaps, applied.run_misses), compared,
                     max_error)


__all__ = ["CURRENTS", "RunReplay", "replay_run", "run_machine"]
