"""Period-by-period probe of a target: the plant (dyno mechanics, speed held) and the target exchange
Measurement and Command as in a run, while the probe sends the Setpoints a run never sends (torque mode, a
disabling Setpoint mid-run, a gap in the measurements, an unknown mode, an unassigned controller id) and
records what the target answered. `probe_target(cfg)` runs the phases in order and returns the findings per
conformance rule (an empty list: the rule held)."""

from __future__ import annotations

from dataclasses import dataclass, field

from pmsm_hil.hil.errors import HilError
from pmsm_hil.hil.mechanics import RPM_TO_RAD_S
from pmsm_hil.hil.pwm import applied_sequence, carrier_half
from pmsm_hil.hil.runner.contract import check_command, describe
from pmsm_hil.hil.runner.lockstep_wait import LockstepWait, WaitEnd, host_stall_error
from pmsm_hil.hil.runner.plant_setup import build_plant
from pmsm_hil.hil.runner.run_config import RunConfig, controller_id
from pmsm_hil.hil.runner.safe_stop import SAFE_STOP_TIMEOUT_S, SafeStop, disable_and_confirm
from pmsm_hil.hil.runner.target_client import HostStallError, TargetError
from pmsm_hil.hil.runner.target_setup import TargetConnection, connect_target
from pmsm_hil.hil.sensors import SensorModel
from pmsm_hil.protocol.errors import ProtocolError
from pmsm_hil.protocol.ids import CONTROLLER_NAMES, Mode, Status
from pmsm_hil.protocol.messages import Command, Fault

#: periods per phase: answers while disabled, torque-mode settling, torque averaging, after a disable
DISABLED_PERIODS, TORQUE_PERIODS, TORQUE_MEAN_PERIODS, SAFE_PERIODS = 10, 150, 50, 10
#: torque mode passes when the mean plant torque is within this fraction of the reference (or 0.2 N·m)
TORQUE_TOLERANCE = 0.1
#: how long a Fault may take to arrive [s] (of the target's own time when the host observes its process, as every
#: wait of the probe: `LockstepWait`; else wall time)
FAULT_TIMEOUT_S = 1.0
#: how long the probe waits for each Command [s]: a board's or an external target's margin on a loaded CI host
#: (wall time); a target process the host observes is judged by its own time, a host stall waited for
PROBE_LOCKSTEP_TIMEOUT_S = 2.0
#: a mode the protocol does not define (0 speed, 1 torque)
UNKNOWN_MODE = 2
#: seq of the probe's first Measurement: half the 16-bit space away from a run just before (which starts at 0),
#: so a target that takes a seq up to 1024 behind its last one for a stale frame (the reference target's
#: decoder, src/pmsm_hil/protocol/assembler.py STALE_WINDOW) sees a new run, not old frames
FIRST_SEQ = 0x8000


@dataclass
class ProbeReport:
    """Findings per rule (empty list: held); `reached`: the rules whose phase ran."""

    findings: dict[str, list[str]] = field(default_factory=dict)
    reached: set[str] = field(default_factory=set)
    #: why the probe stopped early (a link error, a silent target, a refused configuration), "" if it did not
    stopped: str = ""
    #: the rule whose phase runs (a stop is a finding of it, but a host stall's: that rule is not checked)
    current: str = ""
    #: waits that went past their timeout because the host kept the target's process stopped or off the CPUs,
    #: and that time [s] (not counted against the target)
    host_stalls: int = 0
    host_stall_s: float = 0.0

    def add(self, rule: str, finding: str) -> None:
        self.findings.setdefault(rule, []).append(finding)

    def start(self, rule: str) -> None:
        self.reached.add(rule)
        self.findings.setdefault(rule, [])
        self.current = rule


def unassigned_controller_id() -> int:
    """The first controller id no firmware implements (neither a reference controller nor a reserved id)."""
    return min(set(range(1, 255)) - {int(c) for c in CONTROLLER_NAMES})


class Probe:
    """One connection to the target of `cfg` with the plant of its scenario (use a dyno scenario)."""

    def __init__(self, cfg: RunConfig) -> None:
        self.cfg = cfg
        self.cid = controller_id(cfg.controller)
        self.conn: TargetConnection = connect_target(cfg)
        self.client = self.conn.client
        self.plant = build_plant(cfg)
        self.sensors = SensorModel(cfg.sensors, cfg.motor.pole_pairs)
        self.k = FIRST_SEQ
        self.silent = 0
        first = self.conn.duties_at_start(self.plant.sample())  # a board's outputs before its first Command
        self.pending = (Command(seq=0, states=(), durations_ns=(), duties=first) if first
                        else Command(seq=0, states=(0,), durations_ns=(cfg.ts_ns,)))
        self.max_state = cfg.machine.layout.max_state_code
        self.torques: list[float] = []
        own_time, limit_s = self.conn.own_time, cfg.host_stall_limit_s
        self.command_wait = LockstepWait(own_time(cfg.lockstep_timeout_s), cfg.lockstep_timeout_s, limit_s)
        self.fault_wait = LockstepWait(own_time(FAULT_TIMEOUT_S), FAULT_TIMEOUT_S, limit_s)
        #: host stalls of the safe stops so far: count, time [s]
        self.stop_stalls = (0, 0.0)

    def host_stalls(self) -> tuple[int, float]:
        """The waits a host stall prolonged so far, and the time [s] the target could not run in them."""
        waits = (self.command_wait, self.fault_wait)
        return (sum(w.host_stalls for w in waits) + self.stop_stalls[0],
                sum(w.host_stall_s for w in waits) + self.stop_stalls[1])

    def close(self) -> None:
        """Disable the target (waiting for its confirmation) and close the link."""
        try:
            self.disable(Mode.SPEED)
        finally:
            self.conn.close()

    def disable(self, mode: int) -> SafeStop:
        """The disabling Setpoint in `mode`, and what confirmed it (src/pmsm_hil/hil/runner/safe_stop.py: of the
        target's own time when the host observes its process); HostStallError when the host kept the target from
        confirming for the whole host-stall limit."""
        stop = disable_and_confirm(self.client, self.cid, mode=mode, clock=self.conn.own_time(SAFE_STOP_TIMEOUT_S),
                                   stall_limit_s=self.cfg.host_stall_limit_s)
        if stop.host_stall_s > 0:
            self.stop_stalls = (self.stop_stalls[0] + 1, self.stop_stalls[1] + stop.host_stall_s)
        if stop.host_stalled:
            raise HostStallError(stop.observed)
        return stop

    def setpoint(self, *, enable: bool, mode: int, reference: float, cid: int | None = None) -> None:
        self.client.set_setpoint(enable=enable, mode=int(mode), reference=reference,
                                 controller_id=self.cid if cid is None else cid)

    def step(self) -> Command | None:
        """One period: sample, send Measurement k, advance the plant with the command pending, await the reply
        (the lockstep timeout); a valid reply becomes the next pending command, else the zero vector."""
        smp = self.plant.sample()
        self.torques.append(float(smp.torque))
        meas, _ = self.cfg.machine.layout.measure(self.k & 0xFFFF, smp, self.sensors, self.cfg.sensors.ideal,
                                                  self.cfg.motor.vdc)
        self.client.send_measurement(meas)
        cmd = self.pending
        self.plant.advance(*applied_sequence(cmd, self.cfg.ts_ns, carrier_half(self.cfg.pwm_update, self.k)))
        reply = self._await(self.k & 0xFFFF)
        self.client.take_anomalies()
        ok = reply is not None and check_command(reply, self.cfg.ts_ns, self.max_state) is None
        self.silent = 0 if reply is not None else self.silent + 1
        if self.silent > self.cfg.watchdog_periods:
            raise TargetError(f"target silent: no Command for the last {self.silent} Measurements (seq up to "
                              f"{self.k & 0xFFFF})")
        self.pending = reply if ok and reply is not None else Command(seq=0, states=(0,),
                                                                      durations_ns=(self.cfg.ts_ns,))
        self.k += 1
        return reply

    def skip(self, periods: int) -> None:
        """The host stops measuring for `periods` periods (the plant runs on the zero vector, as after a
        host watchdog): the next Measurement's seq jumps."""
        zero = Command(seq=0, states=(0,), durations_ns=(self.cfg.ts_ns,))
        for _ in range(periods):
            self.plant.advance(zero.states, zero.durations_ns)
        self.pending = zero
        self.k += periods

    def _await(self, seq: int) -> Command | None:
        """Command `seq`, within the lockstep timeout (`command_wait`; at once from the in-process target)."""
        cmd = self.client.poll_command(seq)
        if cmd is not None or self.conn.inproc_result is not None:
            return cmd
        wait = self.command_wait
        cmd, end = wait.wait(lambda: self.client.poll_command(seq))
        if end is WaitEnd.HOST_STALL:
            raise self._stalled(wait, f"the Command for seq {seq}")
        return cmd

    def await_fault(self) -> Fault | None:
        """The first Fault since the last call (the link served meanwhile), None after FAULT_TIMEOUT_S
        (`fault_wait`)."""
        wait = self.fault_wait
        fault, end = wait.wait(self._fault)
        if end is WaitEnd.HOST_STALL:
            raise self._stalled(wait, "a FaultTarget")
        return fault

    def _fault(self) -> Fault | None:
        """The first Fault received, after serving the link for a moment when there is none yet."""
        if not self.client.faults:
            self.client.linger(0.002)
        return self.client.faults.pop(0) if self.client.faults else None

    def _stalled(self, wait: LockstepWait, what: str) -> HostStallError:
        clock = wait.clock
        return host_stall_error(clock.pid if clock is not None else 0, wait.wait_s, what, self.cfg.host_stall_limit_s)

    def zero_vector_problem(self, reply: Command | None, seq: int) -> str | None:
        """Why `reply` is not the full-period zero vector answering `seq` (None when it is)."""
        if reply is None:
            return f"no Command for seq {seq}"
        ok = (reply.seq == seq and len(reply.states) == 1 and reply.states[0] in (0, self.max_state)
              and reply.durations_ns == (self.cfg.ts_ns,) and not reply.mirror)
        off = self.conn.outputs_off
        if ok or (reply.seq == seq and off is not None and off(seq)):
            return None  # the zero vector, or a board's gates all off (the open bridge its duties stand for)
        gates = " or, on a board, every gate off (MOE = 0)" if off is not None else ""
        return (f"seq {seq}: {describe(reply)} is not the full-period zero vector (seq echoed, n_states 1, state 0 "
                f"or {self.max_state}, duration Ts = {self.cfg.ts_ns} ns, mirror 0){gates}")


def probe_target(cfg: RunConfig) -> ProbeReport:
    """Run every probe phase against the target of `cfg` (a dyno scenario: the speed is held)."""
    report = ProbeReport()
    try:
        probe = Probe(cfg)
    except (HilError, ProtocolError) as exc:
        report.stopped = f"cannot connect: {exc}"
        return report
    try:
        _phases(probe, report)
    except HostStallError as exc:  # the host's fault: the rule whose phase ran is not checked, not broken
        report.stopped = str(exc)
        report.reached.discard(report.current)
    except (HilError, ProtocolError) as exc:
        report.stopped = str(exc)
        if not report.findings.get(report.current):
            report.add(report.current, f"probe stopped: {exc}")
    finally:
        try:
            probe.close()
        except HostStallError as exc:
            report.stopped = report.stopped or str(exc)
        report.host_stalls, report.host_stall_s = probe.host_stalls()
    return report


def _phases(p: Probe, report: ProbeReport) -> None:
    report.start("config_ack")
    try:
        p.client.configure(p.cfg.target_parameters())
    except TargetError as exc:  # no ack, another value echoed, or a parameter rejected
        report.add("config_ack", str(exc))
        raise
    _disabled_phase(p, report)
    _torque_phase(p, report)
    _safe_state_phase(p, report)
    _watchdog_phase(p, report)
    _fault_phases(p, report)


def _disabled_phase(p: Probe, report: ProbeReport) -> None:
    """Before any enabling Setpoint (and after an explicit disabling one): full-period zero vectors."""
    report.start("setpoint_disabled")
    p.setpoint(enable=False, mode=Mode.SPEED, reference=0.0)
    _expect_zero_vectors(p, report, "setpoint_disabled", DISABLED_PERIODS, "while disabled")


def _torque_phase(p: Probe, report: ProbeReport) -> None:
    """Torque mode: the mean plant torque follows the reference (speed held by the dyno)."""
    report.start("torque_mode")
    m = p.cfg.motor
    ref = 0.5 * m.rated_torque_nm if m.rated_torque_nm > 0 else 1.0
    p.setpoint(enable=True, mode=Mode.TORQUE, reference=ref)
    missing = 0
    for _ in range(TORQUE_PERIODS):
        missing += p.step() is None
    mean = sum(p.torques[-TORQUE_MEAN_PERIODS:]) / TORQUE_MEAN_PERIODS
    tol = max(TORQUE_TOLERANCE * abs(ref), 0.2)
    if abs(mean - ref) > tol:
        report.add("torque_mode", f"Setpoint mode 1 (torque) reference {ref:g} N·m at {_rpm(p):.0f} rpm: mean plant "
                                  f"torque over the last {TORQUE_MEAN_PERIODS} of {TORQUE_PERIODS} periods "
                                  f"{mean:.3f} N·m, outside {ref:g} ± {tol:g} N·m ({missing} periods unanswered)")


def _safe_state_phase(p: Probe, report: ProbeReport) -> None:
    """A disabling Setpoint while running: confirmed by HeartbeatTarget idle (safe_stop), and the very next
    Measurement gets the zero vector, and so on (safe_state)."""
    report.start("safe_stop")
    stop = p.disable(Mode.TORQUE)
    if not stop.confirmed:
        report.add("safe_stop", f"a disabling Setpoint while running in torque mode: {stop.observed}")
    report.start("safe_state")
    _expect_zero_vectors(p, report, "safe_state", SAFE_PERIODS, "Measurement after the disabling Setpoint")


def _watchdog_phase(p: Probe, report: ProbeReport) -> None:
    """Running in speed mode, then the host's watchdog: measurements stop for watchdog_periods, a disabling
    Setpoint follows; the next Measurement (its seq jumped) gets the zero vector echoing the new seq."""
    report.start("watchdog")
    p.setpoint(enable=True, mode=Mode.SPEED, reference=p.plant.sample().omega_m)
    for _ in range(DISABLED_PERIODS):
        p.step()
    p.skip(p.cfg.watchdog_periods)
    p.setpoint(enable=False, mode=Mode.SPEED, reference=0.0)
    _expect_zero_vectors(p, report, "watchdog", 3, f"after {p.cfg.watchdog_periods} periods without a Measurement "
                                                   "and the disabling Setpoint: Measurement")


def _expect_zero_vectors(p: Probe, report: ProbeReport, rule: str, periods: int, context: str) -> None:
    """The next `periods` replies are full-period zero vectors echoing their seq; the first that is not: a
    finding of `rule` ("{context} n: ...")."""
    for i in range(periods):
        seq = p.k & 0xFFFF
        problem = p.zero_vector_problem(p.step(), seq)
        if problem is not None:
            report.add(rule, f"{context} {i + 1} of {periods}: {problem}")
            return


def _fault_phases(p: Probe, report: ProbeReport) -> None:
    """An undefined mode → FaultTarget invalid_config (detail = mode); an unassigned controller id →
    FaultTarget not_implemented (detail = id)."""
    cid = unassigned_controller_id()
    _expect_fault(p, report, "fault_mode", UNKNOWN_MODE, p.cid, Status.INVALID_CONFIG, UNKNOWN_MODE,
                  f"an enabling Setpoint with mode {UNKNOWN_MODE} (defined: 0 speed, 1 torque)")
    _expect_fault(p, report, "fault_controller", Mode.SPEED, cid, Status.NOT_IMPLEMENTED, cid,
                  f"an enabling Setpoint with controller id {cid}, which no firmware implements")


def _expect_fault(p: Probe, report: ProbeReport, rule: str, mode: int, cid: int, code: Status, detail: int,
                  what: str) -> None:
    """Send the enabling Setpoint (mode, cid) and expect FaultTarget (code, detail); disable afterwards."""
    report.start(rule)
    p.client.faults.clear()
    p.setpoint(enable=True, mode=mode, reference=0.0, cid=cid)
    p.step()  # the target may answer the Setpoint while serving a Measurement (in-process: only then)
    fault = p.await_fault()
    expected = f"FaultTarget code {int(code)} ({code.name.lower()}), detail {detail}"
    if fault is None:
        report.add(rule, f"{what}: no FaultTarget within {FAULT_TIMEOUT_S:g} s (expected {expected})")
    elif fault.code != int(code) or fault.detail != detail:
        report.add(rule, f"{what}: FaultTarget code {fault.code}, detail {fault.detail} (expected {expected})")
    p.setpoint(enable=False, mode=Mode.SPEED, reference=0.0)
    p.step()


def _rpm(p: Probe) -> float:
    return float(p.plant.sample().omega_m) / RPM_TO_RAD_S


__all__ = ["Probe", "ProbeReport", "probe_target", "unassigned_controller_id"]
