"""The conformance probe finds each behaviour rule broken by an in-process reference target patched to break it
(and nothing on the unpatched one)."""

from __future__ import annotations

from typing import Any

import pytest

from pmsm_hil.conformance import RULES, broken
from pmsm_hil.conformance.probe import DISABLED_PERIODS, Probe, ProbeReport, probe_target, unassigned_controller_id
from pmsm_hil.conformance.test_conformance import _probe_rule
from pmsm_hil.protocol.ids import CONTROLLER_NAMES, Mode
from pmsm_hil.protocol.messages import ConfigAck, Setpoint
from pmsm_hil.sim_target import target as sim_target
from pmsm_hil.testing.runs import HilSettings, build_config
from tests.firmware_board.test_safe_stop_stall import _stop_for


def _probe(target: str = "inproc", **choices: Any) -> ProbeReport:
    cfg = build_config(HilSettings(target=target), None, {"scenario": "dyno-steady", "speed": 500, "load": 0,
                                                          "settle": 0, **choices})
    return probe_target(cfg)


def _broken_rules(report: ProbeReport) -> set[str]:
    return {rule for rule, found in report.findings.items() if found}


def test_the_reference_target_passes_every_probe_rule() -> None:
    report = _probe()
    assert report.stopped == "" and _broken_rules(report) == set()
    assert report.reached == set(RULES) - {"missing", "sequence", "state_code", "durations", "frame", "duty",
                                           "speed_mode"}


def test_a_target_ignoring_a_disable_while_running(monkeypatch: pytest.MonkeyPatch) -> None:
    real = sim_target.SimTarget._on_setpoint

    def keep_running(self: sim_target.SimTarget, s: Setpoint) -> None:
        if not (self.enabled and not s.enable):
            real(self, s)

    monkeypatch.setattr(sim_target.SimTarget, "_on_setpoint", keep_running)
    report = _probe()
    assert _broken_rules(report) == {"safe_state", "safe_stop", "watchdog"}
    assert "Measurement after the disabling Setpoint " in report.findings["safe_state"][0]
    assert "no HeartbeatTarget in state idle within 500 ms" in report.findings["safe_stop"][0]


@pytest.mark.usefixtures("target_without_heartbeats")
def test_a_target_disabling_without_confirming() -> None:
    report = _probe()
    assert _broken_rules(report) == {"safe_stop"}
    assert report.findings["safe_stop"] == ["a disabling Setpoint while running in torque mode: no HeartbeatTarget in "
                                            "state idle within 500 ms of the disabling Setpoint (no frame at all)"]


def test_a_target_answering_a_disabled_measurement_with_an_active_vector(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sim_target, "_IDLE_STATE", 3)
    report = _probe()
    assert {"setpoint_disabled", "safe_state", "watchdog"} <= _broken_rules(report)
    assert "states=(3,)" in report.findings["setpoint_disabled"][0]


def test_a_target_running_torque_mode_as_speed_mode(monkeypatch: pytest.MonkeyPatch) -> None:
    real = sim_target.SimTarget._on_setpoint

    def speed_only(self: sim_target.SimTarget, s: Setpoint) -> None:
        real(self, Setpoint(s.enable, int(Mode.SPEED) if s.mode == Mode.TORQUE else s.mode, s.reference,
                            s.controller_id))

    monkeypatch.setattr(sim_target.SimTarget, "_on_setpoint", speed_only)
    report = _probe()
    assert _broken_rules(report) == {"torque_mode"}
    message = broken("torque_mode", report.findings["torque_mode"][0])
    assert message.startswith("conformance rule 'torque_mode' broken (Setpoint mode 1")


def test_a_target_without_faults(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(sim_target.SimTarget, "_send", _drop_faults(sim_target.SimTarget._send))
    report = _probe()
    assert _broken_rules(report) == {"fault_mode", "fault_controller"}
    assert "no FaultTarget within" in report.findings["fault_controller"][0]


def _drop_faults(send: Any) -> Any:
    def without_faults(self: sim_target.SimTarget, msg: Any) -> None:
        if type(msg).__name__ != "Fault":
            send(self, msg)
    return without_faults


def test_a_silent_target_stops_the_probe_with_a_finding(monkeypatch: pytest.MonkeyPatch) -> None:
    real = sim_target.SimTarget._on_measurement

    def silent_when_enabled(self: sim_target.SimTarget, m: Any, currents: Any) -> None:
        if not self.enabled:
            real(self, m, currents)

    monkeypatch.setattr(sim_target.SimTarget, "_on_measurement", silent_when_enabled)
    report = _probe()
    assert "target silent" in report.stopped and _broken_rules(report) == {"torque_mode"}
    assert report.reached == {"config_ack", "setpoint_disabled", "torque_mode"}


def test_a_target_echoing_another_config_value(monkeypatch: pytest.MonkeyPatch) -> None:
    real = sim_target.SimTarget._send

    def plus_one(self: sim_target.SimTarget, msg: Any) -> None:
        real(self, ConfigAck(msg.param_id, msg.value + 1.0, msg.status) if isinstance(msg, ConfigAck) else msg)

    monkeypatch.setattr(sim_target.SimTarget, "_send", plus_one)
    report = _probe()
    assert _broken_rules(report) == {"config_ack"} and report.reached == {"config_ack"}
    assert "ConfigAck echo differs" in report.findings["config_ack"][0] and report.stopped


def test_the_unassigned_controller_id_is_no_controller() -> None:
    cid = unassigned_controller_id()
    assert 0 < cid < 255 and cid not in {int(c) for c in CONTROLLER_NAMES}


def _stop_target_mid_probe(monkeypatch: pytest.MonkeyPatch, stop_s: float, stopped: list[int]) -> None:
    """The probe's target process stopped (SIGSTOP) for `stop_s` in the middle of `setpoint_disabled` (where a
    missing Command is a finding) and again at the disabling Setpoint while running (the safe stop's wait);
    `stopped` gets its pid each time."""
    real_step, real_disable = Probe.step, Probe.disable

    def step(self: Probe) -> Any:
        if len(self.torques) == DISABLED_PERIODS // 2 and not stopped:
            stopped.append(self.conn.target_pid())
            _stop_for(stopped[-1], stop_s)
        return real_step(self)

    def disable(self: Probe, mode: int) -> Any:
        if len(stopped) == 1:
            stopped.append(self.conn.target_pid())
            _stop_for(stopped[-1], stop_s)
        return real_disable(self, mode)

    monkeypatch.setattr(Probe, "step", step)
    monkeypatch.setattr(Probe, "disable", disable)


def test_a_target_process_the_host_stopped_is_a_host_stall_not_a_finding(monkeypatch: pytest.MonkeyPatch) -> None:
    """A spawned target stopped 1.5 s while the probe awaits a Command, and again while it awaits the safe stop's
    confirmation: waited for (its own time counts, not wall time), every rule held, both waits counted."""
    stopped: list[int] = []
    _stop_target_mid_probe(monkeypatch, 1.5, stopped)
    report = _probe("spawn")
    assert len(stopped) == 2 and stopped[0] > 0
    assert report.stopped == "" and _broken_rules(report) == set(), report.findings
    assert {"setpoint_disabled", "safe_stop"} <= report.reached
    assert report.host_stalls >= 2 and report.host_stall_s >= 2.0


def test_a_stall_past_the_limit_leaves_the_rule_unchecked_not_broken(monkeypatch: pytest.MonkeyPatch) -> None:
    stopped: list[int] = []
    _stop_target_mid_probe(monkeypatch, 3.0, stopped)
    report = _probe("spawn", host_stall_limit=1.0)
    assert report.stopped.startswith("host stall: the target's process"), report.stopped
    assert "--host-stall-limit 1 s" in report.stopped
    assert _broken_rules(report) == set() and "setpoint_disabled" not in report.reached
    with pytest.raises(pytest.fail.Exception, match="not checked: the probe stopped earlier: host stall"):
        _probe_rule(report, "setpoint_disabled")
