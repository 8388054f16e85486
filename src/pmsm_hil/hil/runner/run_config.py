"""Everything a closed-loop run needs, validated once."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.load_fmu.spec import LoadFmuSpec
from pmsm_hil.hil.machine import Machine, machine_for
from pmsm_hil.hil.machine_params import MachineParams
from pmsm_hil.hil.motor_params import parse_set_options
from pmsm_hil.hil.runner.param_values import check_model_value, check_wire_value
from pmsm_hil.hil.runner.run_groups import (
    GROUPS,
    OperationGroup,
    OutputGroup,
    TargetLinkGroup,
    TimingGroup,
    group_of,
)
from pmsm_hil.hil.runner.run_options import (
    BY_FIELD,
    check_field,
    default_of,
)
from pmsm_hil.hil.runner.scenario import Scenario
from pmsm_hil.hil.sensors import SensorConfig
from pmsm_hil.protocol.errors import LinkSpecError
from pmsm_hil.protocol.ids import CONTROLLER_NAMES, ParamId
from pmsm_hil.protocol.links.faults import FaultSpec, parse_fault_spec
from pmsm_hil.protocol.links.spec import LinkSpec, parse_spec
from pmsm_hil.sim_target.firmware import CONTROLLERS, controller_phases
from pmsm_hil.sim_target.fw_params import FirmwareParamError, FirmwareParamId, firmware_params

if TYPE_CHECKING:  # the FMU's description reader (zipfile, xml) is imported by a run with --load-fmu only
    from pmsm_hil.hil.load_fmu.description import LoadFmuModel

TARGET_KINDS = ("auto", "inproc", "spawn", "external")
#: targets that carry a path: a firmware of the HIL target core built for the host (SIL library, or a source
#: folder built on the fly) or for the emulated MCU (QEMU mps2-an386 ELF); docs/firmware_api.md
TARGET_PREFIXES = ("sil:", "qemu:", "stm32g4:")
#: link specs of a qemu target: its emulated UART0 (default; a Unix socket to QEMU, COBS + CRC-16 serial framing)
#: or the faster mailbox in the board's PSRAM shared with the host (`--link mailbox`)
QEMU_LINK = "serial:qemu-uart0"
QEMU_MAILBOX_LINK = "mailbox:qemu-psram"
#: the link spec of an stm32g4 target: the board's FDCAN1 in this process (parsed as a CAN FD link, never opened)
BOARD_LINK = "virtual:stm32g4-fdcan1,fd=true"

#: the options --link may give a stm32g4 target: the CAN bit rates its FDCAN1 must use [bit/s]
BOARD_LINK_RATES = ("bitrate", "data_bitrate")


def _board_link(link: str) -> str:
    """The link of a stm32g4 target (its own FDCAN1) for --link `link`: "virtual" (the default), or "virtual" with
    the bit rates the firmware's FDCAN1 must use (`virtual,bitrate=1000000,data_bitrate=5000000`)."""
    refusal = (f"--target stm32g4:... is its own link (the board in this process; leave --link out, or state the "
               f"bit rates its FDCAN1 must use: --link virtual,bitrate=N,data_bitrate=M), got --link {link!r}")
    if link == BOARD_LINK:
        return link
    try:
        spec = parse_spec(link)
    except LinkSpecError as exc:
        raise ParameterError(f"--link: {exc}", key="link") from None
    if spec.kind != "virtual" or spec.channel is not None or set(spec.options) - set(BOARD_LINK_RATES):
        raise ParameterError(refusal, key="link")
    return BOARD_LINK + "".join(f",{key}={spec.options[key]}" for key in BOARD_LINK_RATES if key in spec.options)


#: The paper limits the starting torque to ~10 N·m for its 7 N·m machine: 10/7 of rated.
TORQUE_LIMIT_PER_RATED = 10.0 / 7.0


def controller_id(name: str) -> int:
    """Controller id for a CLI name; clear error listing the names."""
    for cid, cname in CONTROLLER_NAMES.items():
        if cname == name:
            return int(cid)
    raise ParameterError(f"unknown controller '{name}' (known: {', '.join(CONTROLLER_NAMES.values())})",
                         key="controller")


#: Named values accepted by --param for enumerated controller parameters.
PARAM_VALUE_NAMES: dict[str, dict[str, float]] = {
    "zero_select": {"paper": 0.0, "min_transitions": 1.0},
}


def parse_param_options(items: list[str] | None) -> dict[str, float]:
    """Parse ``--param NAME=VALUE`` items: numbers, or a named value (e.g. zero_select=min_transitions)."""
    result: dict[str, float] = {}
    numeric: list[str] = []
    for item in items or []:
        name, sep, text = item.partition("=")
        names = PARAM_VALUE_NAMES.get(name.strip().lower())
        if sep and names is not None and text.strip() in names:
            result[name.strip()] = names[text.strip()]
        else:
            numeric.append(item)
    try:
        parsed = parse_set_options(numeric)
    except ParameterError as exc:
        raise ParameterError(str(exc).replace("--set", "--param"), key="param") from None
    return {**parsed, **result}


def param_id(name: str) -> ParamId:
    """Config parameter id for a --param name."""
    try:
        return ParamId[name.upper()]
    except KeyError:
        known = ", ".join(p.name.lower() for p in ParamId)
        raise ParameterError(f"unknown controller parameter '{name}' (known: {known})", key=f"param.{name}") from None


#: ConfigParams that describe the machine itself (a kind's `model_parameters()` and layout extras give them): a
#: controller reading one the motor's kind lacks was written for another kind of machine
MACHINE_MODEL_PARAMS = frozenset({ParamId.RS, ParamId.LD, ParamId.LQ, ParamId.PSI_F, ParamId.LLS, ParamId.RR,
                                  ParamId.LSIGMA, ParamId.LM, ParamId.PSI_R_REF})


#: the PMSM model every controller of the firmware's common parameter set reads, unless it has a model of its own
PMSM_MODEL_PARAMS = frozenset({ParamId.RS, ParamId.LD, ParamId.LQ, ParamId.PSI_F})


def _model_params_read(info: Any) -> frozenset[ParamId]:
    """The machine-model parameters the reference firmware's controller `info` works with: the model parameters
    among its own (beyond the parameters every controller is sent, HIL_FW_PARAMS_COMMON) if it has any (im-foc:
    RR, Lσ, LM, ψR_ref), else the PMSM model of the common set, plus L_ls where it reads it."""
    implemented = [c.params for c in CONTROLLERS if c.implemented and c.name != "off"]
    common = frozenset.intersection(*implemented) if implemented else frozenset()
    own = {ParamId(p) for p in info.params - common if p in {int(m) for m in MACHINE_MODEL_PARAMS}}
    return frozenset(own) if own - {ParamId.LLS} else PMSM_MODEL_PARAMS | own


def _param_id_or_none(name: str) -> ParamId | None:
    try:
        return ParamId[name.strip().upper()]
    except KeyError:
        return None


def check_params_used(controller: str, names: list[str] | dict[str, float], *, option: str = "--param") -> None:
    """ParameterError for a controller parameter the reference firmware's `controller` does not read, naming the
    controllers that do (the firmware's table, CONTROLLERS); `external` (a foreign firmware's own) takes any."""
    info = next((c for c in CONTROLLERS if c.name == controller), None)
    if info is None:
        return
    for name in names:
        pid = int(param_id(name))
        if pid in info.params:
            continue
        users = [c.name for c in CONTROLLERS if pid in c.params]
        where = f"used by {', '.join(users)}" if users else "no controller of the reference firmware reads it"
        raise ParameterError(f"{option} {name}: controller '{controller}' does not use it ({where})",
                             key=f"param.{name}")


@dataclass(frozen=True, slots=True)
class RunConfig:
    """A closed-loop run: motor, controller, scenario, period Ts [s], link and mode, outputs.

    Built from option values by `RunConfig.from_options` (the one path of `hil run`, sweeps, the pytest plugin and
    the benches), or by hand with the keyword arguments below. Read by group (src/pmsm_hil/hil/runner/run_groups.py):
    `machine` (the motor and its kind), `operation` (scenario and load), `target_link` (target, link parsed once
    into `link_spec`, controller, contract and timeouts), `timing` (period, mode, loop, real time), `sensors`,
    `outputs`; each field also reads as an attribute of its own (`cfg.ts_s`).
    """

    motor: MachineParams
    scenario: Scenario
    controller: str = default_of("controller")
    ts_s: float = default_of("ts_s")
    link: str = default_of("link")
    mode: str = default_of("mode")
    target: str = default_of("target")
    seed: int = default_of("seed")
    controller_params: dict[str, float] = field(default_factory=dict)
    sensors: SensorConfig = field(default_factory=SensorConfig)
    out_dir: Path | None = None
    log_trace: bool = default_of("log_trace")
    trace_dt_s: float = 2e-6
    miss_policy: str = default_of("miss_policy")
    watchdog_periods: int = default_of("watchdog_periods")
    lockstep_timeout_s: float = default_of("lockstep_timeout_s")
    #: lockstep: wall time [s] one wait for a Command may last while the host stalls the target's process
    #: (`--host-stall-limit`; then the run ends as a host stall, not the firmware's violation)
    host_stall_limit_s: float = default_of("host_stall_limit_s")
    #: DUT contract findings accepted before the run ends as a violation (counted in `dut_violations`)
    tolerate: int = default_of("tolerate")
    #: real time: a period starting later than this [s] is an overrun (None: Ts / 2)
    overrun_threshold_s: float | None = default_of("overrun_threshold_s")
    #: link fault injection SPEC (`--fault`, docs/runner.md "Link fault injection"); "" = none
    faults: str = ""
    #: qemu targets: the MCU clock of the execution-time estimate [Hz] (`--mcu-clock`)
    mcu_clock_hz: float = default_of("mcu_clock_hz")
    #: stm32g4 targets: the board description (`--board`: a bundled name or a TOML file; None: the default board)
    board: str | None = default_of("board")
    #: the period loop (`--loop`, LOOPS): "auto" runs the C loop (src/pmsm_hil/hil/runner/c/loop.c) where supported
    loop: str = default_of("loop")
    #: real time: SCHED_FIFO priority of the loop thread (`--rt-priority`, 0: none) and its CPU (`--cpu`)
    rt_priority: int = default_of("rt_priority")
    cpu: int | None = default_of("cpu")
    #: real time: the CPUs' wake-up latency held during the run [µs] (`--cpu-dma-latency`, PM QoS; -1: left;
    #: None: 0 when the target runs in another process, where a blocked hand-off is on each period's path)
    cpu_dma_latency_us: int | None = default_of("cpu_dma_latency_us")
    #: sil targets: wall time [s] a step may take before the target is "hung" (`--step-timeout`; the wait for
    #: each Command of an isolated SIL run, in place of `lockstep_timeout_s`)
    step_timeout_s: float = default_of("step_timeout_s")
    #: print a target process's console lines on the terminal as they come (`--verbose`; logged either way)
    verbose: bool = default_of("verbose")
    #: sil targets: load the library into the runner's process (`--sil-in-process`: unprotected, a crash of
    #: the firmware ends the runner) instead of serving it from its own process
    sil_in_process: bool = default_of("sil_in_process")
    #: the mechanical load as an FMU (`--load-fmu`, `--load-fmu-map`, `--load-fmu-set`): replaces the scenario's
    #: load profile; None: the scenario's load
    load_fmu: LoadFmuSpec | None = None
    #: duty-cycle Commands: `--pwm-update` single (carrier period Ts) or double (2·Ts, control at twice
    #: the PWM rate: even periods the rising half of the carrier, odd periods the falling half)
    pwm_update: str = default_of("pwm_update")
    #: the firmware's ADC instant after the period start [s] (`--adc-delay`; 0: at the period start)
    adc_delay_s: float = default_of("adc_delay_s")
    #: `link` parsed once (set by the checks; not an argument)
    link_spec: LinkSpec = field(init=False, repr=False, compare=False)

    @classmethod
    def from_options(cls, values: Mapping[str, Any], sources: Mapping[str, str] | None = None) -> RunConfig:
        """The checked RunConfig of run-option values by key (src/pmsm_hil/hil/runner/run_options.py; tables as dicts or
        `KEY.NAME` items), each value's source by key ("default" when missing) named in errors; see
        src/pmsm_hil/hil/runner/run_inputs.py."""
        from pmsm_hil.hil.runner.run_inputs import from_options

        return from_options(values, sources)

    def __post_init__(self) -> None:
        if self.scenario.rated:  # the one place the motor's ratings become the operating point
            object.__setattr__(self, "scenario",
                               self.scenario.for_motor(self.motor.rated_speed_rpm, self.motor.torque_rating_nm))
        cid = controller_id(self.controller)
        # the firmware's controller table; an id it lacks (external: a foreign firmware's own controller) fits any motor
        needs = controller_phases(cid) if any(c.id == cid for c in CONTROLLERS) else 0
        if needs not in (0, self.machine.phases):
            words = {3: "three", 6: "six"}
            has = self.machine.phases
            raise ParameterError(
                f"controller '{self.controller}' needs a {words.get(needs, needs)}-phase motor, but "
                f"'{self.motor.name}' is {words.get(has, has)}-phase (six-phase motors have lls > 0)", key="controller")
        self._check_machine_model(cid)
        for name in BY_FIELD:  # ranges and choices: the run-option schema's (src/pmsm_hil/hil/runner/run_options.py)
            check_field(name, getattr(self, name))
        if self.adc_delay_ns >= self.ts_ns:
            raise ParameterError(f"--adc-delay must be shorter than the control period Ts = {self.ts_s:g} s (the "
                                 f"Measurement of a period is sampled inside it), got {self.adc_delay_s:g} s",
                                 key="adc_delay")
        if self.target not in TARGET_KINDS:
            prefix = next((p for p in TARGET_PREFIXES if self.target.startswith(p)), None)
            if prefix is None or not self.target[len(prefix):].strip():
                raise ParameterError(f"--target must be one of {', '.join(TARGET_KINDS)}, sil:PATH, qemu:PATH.elf or "
                                     f"stm32g4:PATH.elf, "
                                     f"got {self.target!r}", key="target")
            if prefix == "qemu:":
                if self.link == "virtual":  # the default: the emulated UART is the link
                    object.__setattr__(self, "link", QEMU_LINK)
                elif self.link in ("mailbox", "mailbox:"):
                    object.__setattr__(self, "link", QEMU_MAILBOX_LINK)
                elif self.link not in (QEMU_LINK, QEMU_MAILBOX_LINK):
                    raise ParameterError(f"--target qemu:... talks over the emulated UART (leave --link out) or the "
                                         f"PSRAM mailbox (--link mailbox), got --link {self.link!r}", key="link")
                if self.mode != "lockstep":
                    raise ParameterError("--target qemu:... runs lockstep only (the emulated MCU keeps virtual "
                                         "time, not wall time)", key="mode")
            if prefix == "stm32g4:":
                object.__setattr__(self, "link", _board_link(self.link))
                if self.mode != "lockstep":
                    raise ParameterError("--target stm32g4:... runs lockstep only (the virtual board keeps virtual "
                                         "time, not wall time)", key="mode")
        try:
            object.__setattr__(self, "link_spec", parse_spec(self.link))
        except LinkSpecError as exc:
            raise ParameterError(f"--link: {exc}", key="link") from None
        if self.sil_in_process and not self.target.startswith("sil:"):
            raise ParameterError(f"--sil-in-process: only with --target sil:PATH, got --target {self.target}",
                                 key="sil_in_process")
        if self.faults:
            try:
                parse_fault_spec(self.faults)
            except LinkSpecError as exc:
                raise ParameterError(f"--fault: {exc}", key="fault") from None
        self.resolved_params()  # firmware-declared names and ranges too
        if self.load_fmu is not None:  # the load FMU
            from pmsm_hil.hil.load_fmu.checks import check_load_fmu

            try:
                check_load_fmu(self)
            except ParameterError as exc:
                if exc.key is None:
                    exc.key = "load_fmu"
                raise

    def _check_machine_model(self, cid: int) -> None:
        """ParameterError when the reference firmware's controller `cid` reads a machine-model parameter the motor's
        kind does not give (a PMSM controller on an induction machine, im-foc on a PMSM), naming the controllers
        that run on this motor. A user's --param value counts as given."""
        info = next((c for c in CONTROLLERS if c.id == cid), None)
        if info is None or info.name == "off":
            return
        rated = self.motor.torque_rating_nm
        given = {*self.motor.model_parameters(), *self.machine.layout.target_extras(self.motor, rated)}
        given |= {p for p in (_param_id_or_none(n) for n in self.controller_params) if p is not None}

        def missing(c: Any) -> list[ParamId]:
            return sorted(p for p in _model_params_read(c) if p not in given)

        lacking = missing(info)
        if lacking:
            fits = [c.name for c in CONTROLLERS if c.implemented and c.phases in (0, self.machine.phases)
                    and c.name != "off" and not missing(c)]
            names = ", ".join(p.name.lower() for p in lacking)
            raise ParameterError(
                f"controller '{self.controller}' needs the machine model parameter(s) {names}, which motor "
                f"'{self.motor.name}' (kind {self.machine.layout.kind}) does not have (controllers for it: "
                f"{', '.join(fits) or 'none'})", key="controller")

    @property
    def machine(self) -> Machine:
        """The machine group: the motor's parameters and its kind's descriptor (phase count, plant class, frames,
        record layouts)."""
        return machine_for(self.motor)

    @property
    def operation(self) -> OperationGroup:
        """The scenario and the load group: scenario (operating point, profiles, window), load FMU."""
        return OperationGroup(**group_of(self, GROUPS["operation"]))

    @property
    def target_link(self) -> TargetLinkGroup:
        """The target and link group: who runs the controller, over which link (parsed), its contract and waits."""
        return TargetLinkGroup(**group_of(self, GROUPS["target_link"]))

    @property
    def timing(self) -> TimingGroup:
        """The timing and real-time group: period, mode, loop, PWM update, ADC instant, real-time settings."""
        return TimingGroup(**group_of(self, GROUPS["timing"]))

    @property
    def outputs(self) -> OutputGroup:
        """The outputs group: run directory, trace logging, console echo."""
        return OutputGroup(**group_of(self, GROUPS["outputs"]))

    @property
    def fault_spec(self) -> FaultSpec | None:
        """The parsed `--fault` spec, None when no fault is injected."""
        spec = parse_fault_spec(self.faults) if self.faults else None
        return spec if spec is not None and spec.active else None

    @property
    def overrun_threshold_ns(self) -> int:
        """Real-time lateness [ns] above which a period start is an overrun (default Ts / 2)."""
        return round((self.ts_s / 2 if self.overrun_threshold_s is None else self.overrun_threshold_s) * 1e9)

    @property
    def target_path(self) -> str | None:
        """The PATH of `sil:PATH` / `qemu:PATH`, None for the other target kinds."""
        kind, sep, path = self.target.partition(":")
        return path.strip() if sep and kind + ":" in TARGET_PREFIXES else None

    @property
    def sil_isolated(self) -> bool:
        """A SIL target served from its own process (the default for `sil:PATH`)."""
        return self.target.startswith("sil:") and not self.sil_in_process

    @property
    def load_fmu_model(self) -> LoadFmuModel | None:
        """The checked model description of the load FMU (read once per file version), None without one."""
        if self.load_fmu is None:
            return None
        from pmsm_hil.hil.load_fmu.checks import read_load_fmu_cached

        return read_load_fmu_cached(self.load_fmu)

    @property
    def adc_delay_ns(self) -> int:
        """The ADC instant after the period start [ns] (`--adc-delay`)."""
        return round(self.adc_delay_s * 1e9)

    @property
    def ts_ns(self) -> int:
        """Control period [ns]."""
        return round(self.ts_s * 1e9)

    # firmware-declared parameters (hil_app_params.h, src/pmsm_hil/sim_target/fw_params.py)
    def resolved_params(self) -> dict[ParamId | FirmwareParamId, float]:
        """The --param values by ConfigParam id: a protocol parameter's name, or one the `sil:PATH` / `qemu:PATH`
        firmware declares in its table (its range checked); ParameterError naming an unknown one."""
        protocol = {m.name.lower() for m in ParamId}
        needed = self.target_path is not None and (  # a folder target is built only when its table is needed
            any(n.strip().lower() not in protocol for n in self.controller_params)
            or not Path(self.target_path).expanduser().is_dir())
        declared = {p.name: p for p in firmware_params(self.target_path or "")} if needed else {}
        out: dict[ParamId | FirmwareParamId, float] = {}
        for name, value in self.controller_params.items():
            try:
                out.update(self._resolved_param(declared, name, value))
            except ParameterError as exc:
                raise ParameterError(str(exc), key=f"param.{name}") from None
        return out

    @staticmethod
    def _resolved_param(declared: dict[str, Any], name: str, value: float) -> dict[ParamId | FirmwareParamId, float]:
        """One --param value by its ConfigParam id (see `resolved_params`)."""
        check_wire_value(name, value)  # float32 on the wire (src/pmsm_hil/hil/runner/param_values.py)
        fw = declared.get(name.strip().lower())
        if fw is None:
            try:
                pid = param_id(name)
            except ParameterError as exc:
                if not declared:
                    raise
                raise ParameterError(f"{exc}; the firmware declares: {', '.join(declared)}") from None
            check_model_value(pid, name, value)  # a singular controller model is refused
            return {pid: value}
        try:
            fw.check(value)
        except FirmwareParamError as exc:
            raise ParameterError(str(exc)) from None
        return {fw.param_id: value}

    def target_parameters(self) -> dict[ParamId | FirmwareParamId, float]:
        """Parameters written to the target before enabling: its model of the motor, the speed PI
        and limits, then the user's --param values (which may deliberately mismatch the plant)."""
        m, sc = self.motor, self.scenario
        rated = m.torque_rating_nm
        params: dict[ParamId, float] = {
            **m.model_parameters(),
            ParamId.POLE_PAIRS: float(m.pole_pairs), ParamId.TS: self.ts_s, ParamId.VDC: m.vdc,
            ParamId.SPEED_KP: m.speed_kp, ParamId.SPEED_KI: m.speed_ki,
            ParamId.TORQUE_LIMIT: TORQUE_LIMIT_PER_RATED * rated,
            # a load FMU: its torque after initialisation, written by the native loop before enabling
            ParamId.TORQUE_INTEGRATOR_INIT: sc.start_load_nm if sc.preset_integrator and self.load_fmu is None
            else 0.0,
            ParamId.CURRENT_LIMIT: 0.8 * m.i_trip,
            # the firmware is told the inverter's dead time and minimum pulse (for compensation)
            ParamId.T_DEAD: m.t_dead, ParamId.T_MPW: m.t_mpw,
        }
        params.update(self.machine.layout.target_extras(m, rated))
        out: dict[ParamId | FirmwareParamId, float] = dict(params.items())
        out.update(self.resolved_params())  # firmware-declared parameters
        return out
