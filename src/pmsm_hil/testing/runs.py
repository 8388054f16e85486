"""Closed-loop runs for tests: the choices of `hil run` as keyword arguments, built into a RunConfig by the path
of every run (`RunConfig.from_options`: the same defaults and checks as `hil run`, each value's source named in
errors), run by `run_closed_loop`, signals read back from the run's MCAP (the log on disk is the source of
truth)."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pmsm_hil.errors import HilError
from pmsm_hil.hil.runner.run_options import OPTIONS, RunOption

if TYPE_CHECKING:
    import numpy as np
    import numpy.typing as npt

    from pmsm_hil.hil.runner.run_config import RunConfig
    from pmsm_hil.testing.report import Reporter
    from pmsm_hil.testing.signals import Signal

#: lockstep: how long a test run waits for each Command [s] = `hil run`'s (one policy for the CLI, the plugin and
#: sweeps): a target process the host observes (sil, qemu, spawn) counts only the time it could run, so a loaded
#: CI host stalling it is a host stall, never a false `missing` finding (docs/runner.md "Host stalls")
LOCKSTEP_TIMEOUT_S = float(OPTIONS["lockstep_timeout"].default)
#: `hil run` options the run's own set-up owns (target and link from --hil-target, outputs per run)
_OWNED = frozenset({"target", "link", "out", "overwrite", "no_log", "json"})
_RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)
#: signal name → (PERIOD_DTYPE field, scale, unit); every other scalar field is available by its own name
SIGNALS: dict[str, tuple[str, float, str]] = {
    "speed_rpm": ("omega_m", _RAD_S_TO_RPM, "rpm"),
    "speed_ref_rpm": ("speed_ref", _RAD_S_TO_RPM, "rpm"),
    "torque_nm": ("torque", 1.0, "N·m"),
    "torque_ref_nm": ("torque_ref", 1.0, "N·m"),
    "load_nm": ("load_torque", 1.0, "N·m"),
    **{name: (name, 1.0, "A") for name in ("i_a", "i_b", "i_c", "i_d", "i_q", "i_u", "i_v", "i_w", "i_x", "i_y")},
    "theta_e": ("theta_e", 1.0, "rad"),
    "omega_m": ("omega_m", 1.0, "rad/s"),
    "exec_time_us": ("exec_time_ns", 1e-3, "µs"),
}


class HilRunError(HilError, RuntimeError):
    """A run ended with an internal error of the tool (a bug: the traceback is chained)."""


class SetpointNotHeldError(HilError, AssertionError):
    """A completed run did not hold its setpoint (`setpoint_held` false) and the test expected it to
    (`hil.run(..., expect_hold=False)` to run without the check)."""


@dataclass(frozen=True, slots=True)
class HilSettings:
    """The session's choices: `--hil-target`, `--hil-motor`, `--hil-controller`, `--hil-board`, `--hil-ts`,
    `--hil-out`."""

    target: str = "inproc"
    motor: str | None = None
    controller: str | None = None
    out: Path | None = None
    #: stm32g4 targets: the board description (a bundled name or a TOML file)
    board: str | None = None
    #: the control period [s] unless a run names one
    ts: float | None = None

    def target_values(self) -> dict[str, str]:
        """The run options selecting the target: inproc (virtual bus), spawn (a `hil target` process on UDP),
        external:LINKSPEC (a board on that link), anything else (sil:PATH, qemu:PATH.elf, stm32g4:PATH.elf) as
        the target itself."""
        kind, sep, rest = self.target.partition(":")
        if self.target == "inproc":
            return {"target": "inproc", "link": "virtual"}
        if self.target == "spawn":
            return {"target": "spawn", "link": "udp"}
        if kind == "external" and sep and rest:
            return {"target": "external", "link": rest}
        if kind == "external":
            raise ValueError("--hil-target external needs a link: external:LINKSPEC, e.g. external:socketcan:can0")
        return {"target": self.target}


def run_values(settings: HilSettings, out_dir: Path | None, kwargs: Mapping[str, Any]
               ) -> tuple[dict[str, Any], dict[str, str]]:
    """The run-option values of a run and their sources: the session's target and link (`--hil-target`), motor
    (`--hil-motor`), controller (`--hil-controller`) and output folder, then the keyword arguments (each
    `name=value` the option `name`; `params={k: v}` → `param`, `sets={k: v}` → `set`, `faults=SPEC` → `fault`;
    None: not set), each named "hil.run(NAME=...)" in errors."""
    values: dict[str, Any] = dict(settings.target_values())
    sources = {key: "--hil-target" for key in values}
    if settings.motor is not None:
        values["motor"], sources["motor"] = settings.motor, "--hil-motor"
    if settings.controller is not None and "controller" not in kwargs:
        values["controller"], sources["controller"] = settings.controller, "--hil-controller"
    if settings.board is not None and "board" not in kwargs:
        values["board"], sources["board"] = settings.board, "--hil-board"
    if settings.ts is not None and "ts" not in kwargs:
        values["ts"], sources["ts"] = settings.ts, "--hil-ts"
    if out_dir is not None:
        values["out"], sources["out"] = out_dir, "--hil-out"
    else:
        values["no_log"], sources["no_log"] = True, "--hil-out"
    for name, value in kwargs.items():
        if name in _OWNED:
            raise TypeError(f"hil.run: '{name}' is set by the session (--hil-target, --hil-out), not per run")
        option = run_choice_option(name)
        if value is None:
            continue
        if option.kind == "flag" and not isinstance(value, bool):
            raise TypeError(f"hil.run: '{name}' is a flag (True or False), got {value!r}")
        values[option.key], sources[option.key] = value, f"hil.run({name}=...)"
    return values, sources


#: `hil.run` keyword arguments named for what they hold (tables) beside the option keys
_ALIASES = {"params": "param", "sets": "set", "faults": "fault"}


def run_choice_option(name: str) -> RunOption:
    """The run option a `hil.run` keyword argument sets: a key of the run-option schema
    (src/pmsm_hil/hil/runner/run_options.py) or `params`/`sets`/`faults`; TypeError naming the known ones if none."""
    option = OPTIONS.get(_ALIASES.get(name, name))
    if option is None or option.key in _OWNED:
        known = sorted({*(k for k in OPTIONS if k not in _OWNED), *_ALIASES} - {"param", "set", "fault"})
        raise TypeError(f"hil.run: unknown choice '{name}' (known: {', '.join(known)})")
    return option


def build_config(settings: HilSettings, out_dir: Path | None, kwargs: Mapping[str, Any]) -> RunConfig:
    """The RunConfig `hil run` would build from these choices (ParameterError on a bad one)."""
    from pmsm_hil.hil.runner.run_config import RunConfig

    return RunConfig.from_options(*run_values(settings, out_dir, kwargs))


def execute(settings: HilSettings, out_dir: Path, kwargs: Mapping[str, Any],
            reporter: Reporter | None = None) -> HilResult:
    """Run in `out_dir` (created; must not hold a run) and return the result; prints the metrics table (pytest
    shows it with a failing test). An internal error of the tool is raised (HilRunError from it); a completed run
    that did not hold its setpoint raises SetpointNotHeldError unless `expect_hold=False` is among the choices."""
    from pmsm_hil.app.cli.report_table import format_metrics
    from pmsm_hil.hil.runner.run import run_closed_loop
    from pmsm_hil.hil.runner.run_config import RunConfig

    choices = dict(kwargs)
    expect_hold = choices.pop("expect_hold", True)
    if not isinstance(expect_hold, bool):
        raise TypeError(f"hil.run: 'expect_hold' is True or False, got {expect_hold!r}")
    values, sources = run_values(settings, out_dir, choices)
    cfg = RunConfig.from_options(values, sources)
    out_dir.mkdir(parents=True, exist_ok=True)
    result = run_closed_loop(cfg)
    print("hil.run: " + ", ".join(f"{key}={value}" for key, value in values.items()))
    print(format_metrics(result.metrics))
    if result.outcome.error is not None:
        raise HilRunError(f"hil run ended with an internal error: {result.metrics['end_reason']}") \
            from result.outcome.error
    assert result.mcap_path is not None
    if expect_hold and result.metrics.get("end_code") == 0 and result.metrics.get("setpoint_held") is False:
        err = result.metrics.get("setpoint_error") or {}
        raise SetpointNotHeldError(
            f"setpoint not held: speed {err.get('measured', math.nan):.1f} rpm vs {err.get('reference', math.nan):.1f} "
            f"rpm over the last 10 % of the window (tolerance ±{result.metrics.get('hold_tolerance_pct')} %); "
            f"hil.run(..., expect_hold=False) runs without this check, hold_tolerance=PCT widens it")
    return HilResult(result.metrics, result.mcap_path, out_dir,
                     (cfg.scenario.settle_s, cfg.scenario.total_s), reporter)


class HilResult:
    """One run: `metrics` (the metrics.json dict), `end_code`, `end_reason`, `mcap_path`, `out_dir`, the metrics
    `window` (t0, t1) [s], and `signal(name)` read from the MCAP."""

    def __init__(self, metrics: dict[str, Any], mcap_path: Path, out_dir: Path, window: tuple[float, float],
                 reporter: Reporter | None = None) -> None:
        self.metrics = metrics
        self.mcap_path = mcap_path
        self.out_dir = out_dir
        self.window = window
        self.reporter = reporter
        self._periods: npt.NDArray[np.void] | None = None

    @property
    def end_code(self) -> int:
        """How the run ended (= `hil run`'s exit code: 0 completed, 3 safety stop, 4 DUT violation, ...)."""
        return int(self.metrics["end_code"])

    @property
    def end_reason(self) -> str:
        """`completed`, or why the run ended."""
        return str(self.metrics["end_reason"])

    @classmethod
    def load(cls, out_dir: Path) -> HilResult:
        """The result of a run already on disk (its run.mcap and metrics.json)."""
        from pmsm_hil.hil.runlog.reader import read_metadata

        out_dir = Path(out_dir)
        metrics = json.loads((out_dir / "metrics.json").read_text(encoding="utf-8"))
        scenario = json.loads(read_metadata(out_dir / "run.mcap").get("scenario_params", "{}"))
        settle = float(scenario.get("settle_s", 0.0))
        return cls(metrics, out_dir / "run.mcap", out_dir, (settle, settle + float(scenario.get("duration_s", 0.0))))

    @property
    def periods(self) -> npt.NDArray[np.void]:
        """Every period record of the run (PERIOD_DTYPE), read once from the MCAP."""
        if self._periods is None:
            from pmsm_hil.hil.runlog.reader import read_periods

            self._periods = read_periods(self.mcap_path)
        return self._periods

    @property
    def signal_names(self) -> tuple[str, ...]:
        """Names `signal` accepts."""
        names = self.periods.dtype.names or ()
        raw = [n for n in names if self.periods.dtype[n].shape == () and n not in SIGNALS]
        return (*SIGNALS, *raw)

    def signal(self, name: str) -> Signal:
        """Signal `name` over the whole run (settling included): t = period start [s], t = 0 at the first."""
        from pmsm_hil.testing.signals import Signal

        periods = self.periods
        field, scale, unit = SIGNALS.get(name, (name, 1.0, ""))
        if name not in self.signal_names or field not in (periods.dtype.names or ()):
            raise ValueError(f"unknown signal '{name}' (known: {', '.join(self.signal_names)})")
        y = periods[field].astype("f8") * scale
        return Signal(name, periods["t"].astype("f8"), y, unit, self.reporter)


__all__ = ["LOCKSTEP_TIMEOUT_S", "SIGNALS", "HilResult", "HilRunError", "HilSettings", "SetpointNotHeldError",
           "build_config", "execute", "run_choice_option", "run_values"]
