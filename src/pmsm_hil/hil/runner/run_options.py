"""The run-configuration schema, declared once: every option of a closed-loop run with its key, kind, default,
choices, range, unit and help.

Everything else is generated from `RUN_OPTIONS`: the `hil run` / `hil bench loop` / `hil sweep` argparse
options (src/pmsm_hil/app/cli/run.py), the `--config FILE.toml` keys and the sweep keys
(src/pmsm_hil/app/cli/config_file.py, src/pmsm_hil/app/sweep/plan.py), the keyword arguments of the pytest plugin's
`hil.run(...)` (src/pmsm_hil/testing/runs.py), the defaults a run uses (`DEFAULTS`, also the defaults of `RunConfig`'s
fields) and `RunConfig`'s range checks (`check_field`). A key is the option's long name without dashes, `-` as `_`
(`--miss-policy` → `miss_policy`). Every option is held by the `RunConfig` (`field`, or `part`: the attribute it goes
into with others, e.g. `--speed` into `scenario.speed_rpm`) or is `cli_only` (what `hil run` does after the run:
`--json`, `--overwrite`, `--expect-hold`); `RunConfig.from_options` (src/pmsm_hil/hil/runner/run_inputs.py) turns option
values into a RunConfig.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from pmsm_hil.hil.control_period import MAX_TS_S, MIN_TS_S, TS_RANGE_WORDS, check_control_period
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.pwm import PWM_UPDATES
from pmsm_hil.hil.runner.scenario import SHAFTS

Kind = Literal["number", "integer", "frequency", "choice", "text", "path", "flag", "table"]
#: run: every command that runs the closed loop (`hil run`, `hil bench loop`, `hil sweep`, `hil.run`);
#: output: `hil run`'s files (never swept: a sweep owns its outputs)
Scope = Literal["run", "output"]

MODES = ("lockstep", "realtime")
#: the period loop: "auto" = native (the C loop); "python" is the test suite's reference loop
LOOPS = ("auto", "native", "python")
MISS_POLICIES = ("hold", "zero")

DEFAULT_MCU_CLOCK_HZ = 168e6
#: the longest wall-time wait for one Command [s] (lockstep and SIL step timeouts)
MAX_WAIT_S = 3600.0


@dataclass(frozen=True, slots=True)
class RunOption:
    """One option of a run. `minimum`/`maximum` bound numbers (`open_minimum`: the bound itself is refused);
    `field` is the `RunConfig` attribute holding the value (None: consumed before the RunConfig is built);
    `default` is the value a run uses when neither the command line nor a config file sets it (None: none, or
    the scenario's); `help` may be a callable for texts computed from the registries."""

    key: str
    kind: Kind
    help: str | Callable[[], str]
    default: Any = None
    field: str | None = None
    unit: str = ""
    minimum: float | None = None
    maximum: float | None = None
    open_minimum: bool = False
    choices: tuple[str, ...] = ()
    metavar: str | None = None
    scope: Scope = "run"
    #: how --help names the default when it is not `default` itself ("" : say nothing)
    default_text: str | None = None
    #: the argparse destination when it is not the key (`--set` → `set_params`)
    dest: str | None = None
    #: a table (`--param`) also takes named values (strings), e.g. zero_select = "min_transitions"
    table_text: bool = False
    #: the accepted range in words when the bounds alone do not say it (why they are what they are)
    range_words: str | None = None
    #: the RunConfig attribute (dotted: inside it) the value goes into with other options' values, when `field` is
    #: None: `--speed` → "scenario.speed_rpm", `--set` → "motor"
    part: str | None = None
    #: used by `hil run` after the run only (not part of a run's configuration): --json, --overwrite, --expect-hold
    cli_only: bool = False
    #: the check of a value when the bounds alone are not it (`--ts`: src/pmsm_hil/hil/control_period.py, its one
    #: check): called with the value and the option's name, raises ParameterError
    validate: Callable[[Any, str], object] | None = None

    @property
    def option(self) -> str:
        """The long command-line option, e.g. `--miss-policy`."""
        return "--" + self.key.replace("_", "-")

    @property
    def target(self) -> str:
        """The argparse destination."""
        return self.dest or self.key

    def help_text(self) -> str:
        """The help line with the default the run really uses."""
        text = self.help() if callable(self.help) else self.help
        if self.default_text is not None:
            return text + (f" (default {self.default_text})" if self.default_text else "")
        if self.default is None or self.kind in ("flag", "table"):
            return text
        shown = f"{self.default:g}" if isinstance(self.default, float) else str(self.default)
        return f"{text} (default {shown})"

    def parse(self, text: str, *, check: bool = True) -> Any:
        """The value of `text` as this option holds it; ParameterError naming the option if it is not one (or,
        with `check`, out of range: the command line checks ranges later, in `RunConfig.from_options`, for one-line
        errors naming where the value came from)."""
        raw = text.strip()
        if self.kind == "number":
            value: Any = _float(raw, self.option, self.key)
        elif self.kind == "integer":
            try:
                value = int(raw)
            except ValueError:
                raise ParameterError(f"{self.option} must be an integer, got {text!r}", key=self.key) from None
        elif self.kind == "frequency":
            value = _frequency(raw, self.option, text, self.key)
        elif self.kind == "path":
            value = Path(raw)
        else:
            value = text
        return self.check(value) if check else value

    def check(self, value: Any) -> Any:
        """`value` if it is in this option's range / choices; else ParameterError naming the option."""
        if value is None:
            return value
        if self.kind == "choice":
            if value not in self.choices:
                raise ParameterError(f"{self.option} must be one of {', '.join(self.choices)}, got {value!r}",
                                     key=self.key)
            return value
        if self.kind not in ("number", "integer", "frequency"):
            return value
        if self.validate is not None:
            try:
                self.validate(value, self.option)
            except ParameterError as exc:
                raise ParameterError(str(exc), key=self.key) from None
            return value
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise ParameterError(f"{self.option} must be {self.range_text()}, got {value!r}", key=self.key)
        low, high = self.minimum, self.maximum
        too_low = low is not None and (value <= low if self.open_minimum else value < low)
        too_high = high is not None and value > high
        if too_low or too_high:
            raise ParameterError(f"{self.option} must be {self.range_text()}, got {value!r}", key=self.key)
        return value

    def range_text(self) -> str:
        """The accepted range in words, e.g. "> 0 s" or "in [1e+06, 2e+09] Hz"."""
        if self.range_words is not None:
            return self.range_words
        unit = f" {self.unit}" if self.unit else ""
        low, high = self.minimum, self.maximum
        if low is not None and high is not None:
            return f"in {'(' if self.open_minimum else '['}{low:g}, {high:g}]{unit}"
        if low is not None:
            return f"{'>' if self.open_minimum else '≥'} {low:g}{unit}"
        if high is not None:
            return f"≤ {high:g}{unit}"
        return "a finite number"


def _float(raw: str, option: str, key: str | None = None) -> float:
    try:
        value = float(raw)
    except ValueError:
        raise ParameterError(f"{option} must be a number, got {raw!r}", key=key) from None
    if not math.isfinite(value):
        raise ParameterError(f"{option} must be finite, got {raw!r}", key=key)
    return value


_FREQUENCY_UNITS = (("ghz", 1e9), ("mhz", 1e6), ("khz", 1e3), ("hz", 1.0))


def _frequency(raw: str, option: str, text: str, key: str | None = None) -> float:
    """Hz, or a number with kHz / MHz / GHz."""
    number, scale = raw.lower().replace(" ", ""), 1.0
    for unit, factor in _FREQUENCY_UNITS:
        if number.endswith(unit):
            number, scale = number[: -len(unit)], factor
            break
    try:
        value = float(number) * scale
    except ValueError:
        raise ParameterError(f"{option}: expected a frequency (e.g. 168e6 or 168MHz), got {text!r}",
                             key=key) from None
    return value


def _controllers() -> str:
    from pmsm_hil.protocol.ids import CONTROLLER_NAMES

    return f"controller: {', '.join(CONTROLLER_NAMES.values())}"


def _motors() -> str:
    from pmsm_hil.hil.presets_loader import preset_names

    return f"bundled preset ({', '.join(preset_names())}) or a TOML motor file"


def _settable() -> str:
    from pmsm_hil.hil.motor_params import SETTABLE_UNITS

    return "override a motor parameter (SI units): " + ", ".join(
        f"{k} [{u}]" if u else k for k, u in SETTABLE_UNITS.items())


def _scenarios() -> str:
    from pmsm_hil.hil.runner.scenario import scenario_names

    return f"{' | '.join(scenario_names())} | FILE.toml"


def _steady(what: str) -> Callable[[], str]:
    """Help for an option whose default is the scenario's: names the default scenario's value."""
    def text() -> str:
        from pmsm_hil.hil.runner.scenario import load_scenario

        steady = load_scenario(str(DEFAULTS["scenario"]))
        value = {"speed": steady.speed_rpm, "load": steady.load_nm, "duration": steady.duration_s,
                 "settle": steady.settle_s}[what]
        if steady.at_rated and what in ("speed", "load"):
            rated = {"speed": "rated speed", "load": "rated torque"}[what]
            return (f"{_SCENARIO_HELP[what]} (default: the scenario's; {steady.name}: the motor's {rated}, "
                    f"{value:g} for {DEFAULTS['motor']})")
        return f"{_SCENARIO_HELP[what]} (default: the scenario's; {steady.name}: {value:g})"
    return text


_SCENARIO_HELP = {
    "speed": "speed reference [rpm]",
    "load": "load torque [N·m]",
    "duration": "metrics window [s], settling on top; longer runs are refused when their buffers exceed half "
                "the memory available (docs/runner.md)",
    "settle": "settling time before the window [s]",
}


def _links() -> str:
    from pmsm_hil.protocol.links.kinds import LINK_KINDS, PYTHON_CAN_ADAPTER

    return "link: " + "; ".join(k.summary for k in LINK_KINDS.values()) + "; " + PYTHON_CAN_ADAPTER.summary


RUN_OPTIONS: tuple[RunOption, ...] = (
    RunOption("motor", "text", _motors, "niu2020-ipmsm", metavar="PRESET|FILE", part="motor"),
    RunOption("set", "table", _settable, metavar="NAME=VALUE", dest="set_params", part="motor"),
    RunOption("controller", "text", _controllers, "mpcc", field="controller", metavar="NAME"),
    RunOption("scenario", "text", _scenarios, "steady", metavar="NAME|FILE.toml", part="scenario"),
    RunOption("speed", "number", _steady("speed"), metavar="RPM", unit="rpm", part="scenario.speed_rpm"),
    RunOption("load", "number", _steady("load"), metavar="NM", unit="N·m", part="scenario.load_nm"),
    RunOption("duration", "number", _steady("duration"), metavar="S", unit="s", minimum=0.0, open_minimum=True,
              part="scenario.duration_s"),
    RunOption("settle", "number", _steady("settle"), metavar="S", unit="s", minimum=0.0, part="scenario.settle_s"),
    RunOption("theta0", "number", "initial electrical rotor angle [rad] (default: the scenario's, 0)", metavar="RAD",
              unit="rad", part="scenario.theta0_rad"),
    # the shaft between motor and load (inertia mechanics; src/pmsm_hil/hil/mechanics.py, docs/plant.md "Mechanics")
    RunOption("shaft", "choice",
              "the shaft between the motor and its load: rigid (one mass, the motor's j) or two-mass (the motor's j "
              "and --load-inertia on a shaft of --shaft-stiffness and --shaft-damping; the load torque acts on the "
              "load mass)", choices=SHAFTS, default_text="the scenario's, rigid", part="scenario.shaft"),
    RunOption("load_inertia", "number", "two-mass shaft: the load mass's inertia [kg·m²]", metavar="KGM2",
              unit="kg·m²", minimum=0.0, open_minimum=True, part="scenario.load_inertia_kgm2"),
    RunOption("shaft_stiffness", "number", "two-mass shaft: torsional stiffness [N·m/rad]", metavar="NM_PER_RAD",
              unit="N·m/rad", minimum=0.0, open_minimum=True, part="scenario.shaft_stiffness_nm_per_rad"),
    RunOption("shaft_damping", "number", "two-mass shaft: torsional damping [N·m·s/rad]", metavar="NMS_PER_RAD",
              unit="N·m·s/rad", minimum=0.0, default_text="the scenario's, 0",
              part="scenario.shaft_damping_nms_per_rad"),
    RunOption("ts", "number", "control period [s], a whole number of ns", 100e-6, field="ts_s", metavar="S",
              unit="s", minimum=MIN_TS_S, maximum=MAX_TS_S, range_words=TS_RANGE_WORDS,
              validate=check_control_period),
    RunOption("link", "text", _links, "virtual", field="link", metavar="SPEC"),
    RunOption("mode", "choice", "virtual time or wall-clock pacing", "lockstep", field="mode", choices=MODES),
    RunOption("target", "text",
              "who runs the target: auto (virtual → in-process), inproc, spawn a `hil target` process, external (a "
              "real board), sil:PATH (a firmware built with `hil fw build --board host`, or its source folder, "
              "served from its own process), qemu:PATH.elf (a firmware built for mps2-an386, run in QEMU over its "
              "emulated UART) or stm32g4:PATH.elf (an STM32G4 firmware on the virtual board; docs/firmware_api.md)",
              "auto", field="target", metavar="KIND"),
    RunOption("board", "text",
              "stm32g4 targets: the board description, a bundled name or a TOML file (docs/firmware_api.md \"The "
              "virtual board\")", field="board", metavar="NAME_OR_FILE", default_text="nucleo_g474re_ihm"),
    RunOption("mcu_clock", "frequency",
              "qemu targets: MCU clock of the execution-time estimate, Hz or with a unit (168MHz)",
              DEFAULT_MCU_CLOCK_HZ, field="mcu_clock_hz", metavar="HZ", unit="Hz", minimum=1e6, maximum=2e9,
              default_text="168 MHz", range_words="between 1 MHz and 2 GHz"),
    RunOption("step_timeout", "number",
              "sil targets: wall time a firmware step may take before the target is 'hung' (exit 3) [s]; the wait "
              "for each Command of a SIL run, in place of --lockstep-timeout", 0.5, field="step_timeout_s",
              metavar="S", unit="s", minimum=0.0, maximum=MAX_WAIT_S, open_minimum=True),
    RunOption("sil_in_process", "flag",
              "sil targets: load the library into this process (UNPROTECTED: a crash of the firmware ends `hil run` "
              "without metrics, an endless loop hangs it) instead of its own process", False,
              field="sil_in_process"),
    RunOption("verbose", "flag",
              "print what a target process writes (a SIL firmware's printf, its stderr) on the terminal as it comes; "
              "it is in the run's MCAP (/target/console) either way", False, field="verbose"),
    RunOption("seed", "integer", "seed for sensor noise", 0, field="seed", minimum=0),
    RunOption("param", "table", "controller parameter (SI units), e.g. lambda=0.5, t_thr=8e-6, speed_kp=0.8",
              metavar="NAME=VALUE", table_text=True, part="controller_params"),
    RunOption("miss_policy", "choice", "real time: a late command → hold last/zero", "hold", field="miss_policy",
              choices=MISS_POLICIES),
    RunOption("watchdog_periods", "integer", "silent-target periods before the safe state", 10,
              field="watchdog_periods", minimum=1),
    RunOption("tolerate", "integer",
              "DUT contract violations accepted before the run ends as one (counted in dut_violations)", 0,
              field="tolerate", minimum=0),
    RunOption("lockstep_timeout", "number",
              "lockstep: time to wait for each Command before it is missing [s]; a target process the host can "
              "observe (sil, qemu, spawn) counts only the time it could run (a host stall does not count), a "
              "board wall time", 0.5, field="lockstep_timeout_s", unit="s", minimum=0.0, maximum=MAX_WAIT_S,
              open_minimum=True),
    RunOption("host_stall_limit", "number",
              "lockstep: wall time one wait for a Command may last while the host keeps the target's process "
              "stopped or off the CPUs before the run ends as a host stall (exit 1) [s]", 60.0,
              field="host_stall_limit_s", unit="s", minimum=0.0, maximum=MAX_WAIT_S, open_minimum=True),
    RunOption("fault", "text",
              "link fault injection on the host's link: drop=P,dup=P,corrupt=P,delay=D,jitter=D,reorder=P,"
              "silence=T0:T1,seed=S (KEY.up / KEY.down per direction; docs/runner.md)", field="faults",
              metavar="SPEC"),
    RunOption("loop", "choice",
              "the period loop: the C loop (src/pmsm_hil/hil/runner/c/loop.c) runs every run (auto = native); "
              "python is the test suite's reference loop, not part of the product (an error outside the tests)", "auto",
              field="loop", choices=LOOPS),
    RunOption("pwm_update", "choice",
              "duty-cycle Commands: the PWM timer's compare values loaded once per carrier period (single: carrier "
              "period = Ts, valley at each period start) or twice (double: control at twice the PWM rate, carrier "
              "period 2·Ts; docs/firmware_api.md)", "single", field="pwm_update", choices=PWM_UPDATES),
    RunOption("adc_delay", "number",
              "the firmware's ADC instant after the period start (the carrier valley; double update: valley or peak) "
              "[s]: the Measurement is the plant sampled there, from the period's own gate sequence (the records "
              "keep the period-start samples; docs/firmware_api.md)", 0.0, field="adc_delay_s", unit="s",
              minimum=0.0, default_text="0: at the period start"),
    RunOption("rt_priority", "integer",
              "real time, native loop: SCHED_FIFO priority 1..99 of the loop thread (refused without CAP_SYS_NICE, "
              "said in the warnings)", 0, default_text="0: none", field="rt_priority", metavar="N", minimum=0,
              maximum=99,
              range_words="0 (none) or a SCHED_FIFO priority 1..99"),
    RunOption("cpu", "integer", "real time, native loop: pin the loop thread to this CPU", field="cpu", metavar="N",
              minimum=0, default_text="any"),
    RunOption("cpu_dma_latency", "integer",
              "real time: hold every CPU's wake-up latency at most US µs for the run (PM QoS through "
              "/dev/cpu_dma_latency, as cyclictest does; 0: idle CPUs poll, a blocked receive wakes in µs instead "
              "of tens of µs; needs root, refused: a warning); -1 leaves the kernel's setting",
              None, field="cpu_dma_latency_us", metavar="US", minimum=-1, maximum=2_000_000_000,
              default_text="0 when the target runs in another process, else -1",
              range_words="-1 (leave it) or a latency of 0 µs or more"),
    RunOption("overrun_threshold", "number", "real time: a period starting later than this is an overrun [s]",
              field="overrun_threshold_s", unit="s", minimum=0.0, open_minimum=True, default_text="Ts/2"),
    RunOption("adc_lsb", "number", "current quantisation step [A]", 0.0, unit="A", minimum=0.0,
              default_text="0: ideal", part="sensors.adc_lsb_a"),
    RunOption("noise", "number", "current noise standard deviation [A]", 0.0, unit="A", minimum=0.0,
              default_text="0: none", part="sensors.noise_std_a"),
    RunOption("encoder_counts", "integer", "encoder counts/rev", 0, minimum=0, default_text="0: ideal angle",
              part="sensors.encoder_counts"),
    # the mechanical load as an FMU (src/pmsm_hil/hil/load_fmu, docs/plant.md "Load as an FMU"): the three
    # make RunConfig.load_fmu (a LoadFmuSpec)
    RunOption("load_fmu", "path",
              "the mechanical load as an FMU (FMI 2.0/3.0 Co-Simulation, replaces the scenario's load): input speed "
              "[rad/s], output torque [N·m], one doStep(Ts) per period in the C loop", metavar="PATH.fmu",
              part="load_fmu"),
    RunOption("load_fmu_map", "text",
              "the FMU's names for the speed input and torque output, e.g. speed=w_shaft,torque=T_load",
              metavar="ROLE=NAME,...", default_text="speed=speed,torque=torque", part="load_fmu"),
    RunOption("load_fmu_set", "table", "a parameter of the load FMU set before its initialisation (repeatable)",
              metavar="NAME=VALUE", part="load_fmu"),
    RunOption("load_fmu_isolation", "choice",
              "where the load FMU runs: process (its own process: a crash, exit or hang ends the run with exit 3, "
              "the host unharmed) or none (in the run's process, unprotected: a crash kills the run)", "process",
              choices=("process", "none"), part="load_fmu"),
    # `hil run`'s outputs
    RunOption("out", "path", "output directory for run.mcap and metrics.json; an existing run there is refused "
              "unless --overwrite", scope="output", default_text="runs/<time>-<controller>", part="out_dir"),
    RunOption("overwrite", "flag", "replace the run in --out (its run.mcap and metrics.json are removed first)",
              False, scope="output", cli_only=True),
    RunOption("no_log", "flag", "do not write an MCAP log", False, scope="output", part="out_dir"),
    RunOption("log_trace", "flag", "also log the 2 µs plant trace", False, field="log_trace", scope="output"),
    RunOption("json", "path", "write the metrics as JSON to this file", scope="output", cli_only=True),
    # the setpoint verdict (src/pmsm_hil/hil/runner/setpoint_hold.py)
    RunOption("hold_tolerance", "number", "setpoint_held: largest error of the mean speed over the last 10 percent "
              "of the metrics window [percent of the reference, at least 5 rpm]", metavar="PCT", unit="percent",
              minimum=0.0, open_minimum=True, default_text="the scenario's hold_tolerance_pct, else 2",
              part="scenario.hold_tolerance_pct"),
    RunOption("expect_hold", "flag", "a completed run whose setpoint was not held (setpoint_held false) exits 5",
              False, scope="output", cli_only=True),
)

#: options by key
OPTIONS: dict[str, RunOption] = {o.key: o for o in RUN_OPTIONS}
#: the value a run uses for each key when nobody sets it (None: none, or the scenario's)
DEFAULTS: dict[str, Any] = {o.key: o.default for o in RUN_OPTIONS}
#: RunConfig attribute → its option
BY_FIELD: dict[str, RunOption] = {o.field: o for o in RUN_OPTIONS if o.field is not None}


def default_of(field: str) -> Any:
    """The default of the RunConfig attribute `field` (its option's)."""
    return BY_FIELD[field].default


def check_field(field: str, value: Any) -> Any:
    """`value` of the RunConfig attribute `field` checked against its option (ParameterError naming it)."""
    return BY_FIELD[field].check(value)


__all__ = ["BY_FIELD", "DEFAULTS", "DEFAULT_MCU_CLOCK_HZ", "LOOPS", "MAX_TS_S", "MAX_WAIT_S", "MIN_TS_S",
           "MISS_POLICIES", "MODES", "OPTIONS", "RUN_OPTIONS", "RunOption", "check_field", "default_of"]
