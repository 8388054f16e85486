"""The examples in examples/ run (short) and produce what they print."""

from __future__ import annotations

import dataclasses
import math
import runpy
import socket
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from pmsm_hil.hil.mechanics import DynoMechanics
from pmsm_hil.hil.plant import Plant
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.protocol.codec import PROFILES, FrameCodec, decode_message
from pmsm_hil.protocol.ids import ControllerId, Mode, ParamId, Status
from pmsm_hil.protocol.messages import Command, ConfigAck, ConfigParam, Fault, Measurement, Setpoint

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_plant_step_response_example(capsys: pytest.CaptureFixture[str]) -> None:
    module = runpy.run_path(str(EXAMPLES / "plant_step_response.py"))
    torques = module["main"](3)
    assert len(torques) == 3 and capsys.readouterr().out.count("torque =") == 3


def test_closed_loop_api_example(capsys: pytest.CaptureFixture[str]) -> None:
    module = runpy.run_path(str(EXAMPLES / "closed_loop_api.py"))
    results = module["main"](0.02)
    assert set(results) == {"mpcc", "dsvm-20"}
    assert all(abs(m["torque_mean_nm"] - 7.0) < 0.5 for m in results.values())
    assert "dsvm-20" in capsys.readouterr().out


def _python_target() -> Any:
    return runpy.run_path(str(EXAMPLES / "python_target.py"))["ExampleTarget"]()


def _configure(target: Any, motor: Any) -> None:
    values = {ParamId.RS: motor.rs, ParamId.LD: motor.ld, ParamId.LQ: motor.lq, ParamId.PSI_F: motor.psi_f,
              ParamId.POLE_PAIRS: float(motor.pole_pairs), ParamId.TS: 100e-6, ParamId.VDC: motor.vdc,
              ParamId.TORQUE_LIMIT: 10.0}
    for pid, value in values.items():
        assert target.handle(ConfigParam(int(pid), value)) == [ConfigAck(int(pid), value, int(Status.OK))]
    [nan_ack] = target.handle(ConfigParam(int(ParamId.LD), math.nan))  # refused, value echoed
    assert nan_ack.status == Status.INVALID_CONFIG and math.isnan(nan_ack.value)
    assert target.p(ParamId.LD) == motor.ld


def test_python_target_example_follows_the_protocol() -> None:
    target = _python_target()
    _configure(target, load_motor("niu2020-ipmsm"))
    meas = Measurement(seq=41, i_a=1.0, i_b=-0.5, i_c=-0.5, theta_e=0.3, omega_m=157.0, vdc=311.0)
    # disabled (no setpoint yet): a full-period zero vector echoing the seq
    assert target.handle(meas) == [Command(seq=41, states=(0,), durations_ns=(100_000,))]
    # a controller id it does not implement: a Fault naming the id, and it stays disabled
    assert target.handle(Setpoint(True, int(Mode.SPEED), 157.0, int(ControllerId.MPCC))) == [
        Fault(node=1, code=int(Status.NOT_IMPLEMENTED), detail=int(ControllerId.MPCC))]
    assert target.handle(meas)[0].states == (0,)
    assert target.handle(Setpoint(True, int(Mode.TORQUE), 7.0, int(ControllerId.EXTERNAL))) == []
    (cmd,) = target.handle(dataclasses.replace(meas, seq=42))
    assert cmd.seq == 42 and sum(cmd.durations_ns) == 100_000 and cmd.states[0] in range(1, 7)
    for profile in PROFILES:  # the replies are valid frames of both profiles
        assert decode_message(FrameCodec(profile).encode(cmd)) == cmd


@pytest.mark.parametrize(("rpm", "torque_nm"), [(1500.0, 7.0), (300.0, -3.0), (-1000.0, 5.0)])
def test_python_target_example_drives_the_plant_from_the_documented_conventions(rpm: float, torque_nm: float) -> None:
    """The example's law knows only docs/protocol.md's conventions (angle zero, rotation, Clarke scaling,
    switch polarity); closing the loop on the plant by hand (one period of delay) gives the torque asked,
    within 10 % (one vector per period ripples; a power-invariant Clarke would be 18 % off, a wrong sign or
    angle zero far more)."""
    motor = load_motor("niu2020-ipmsm")
    target = _python_target()
    _configure(target, motor)
    target.handle(Setpoint(True, int(Mode.TORQUE), torque_nm, int(ControllerId.EXTERNAL)))
    plant = Plant(motor, 100e-6, DynoMechanics(rpm))
    in_flight: tuple[int, ...] = (0,)
    torques = []
    for k in range(400):
        s = plant.sample()
        (cmd,) = target.handle(Measurement(k, s.i_a, s.i_b, s.i_c, s.theta_e, s.omega_m, s.vdc))
        plant.advance(in_flight, [100_000])
        in_flight = cmd.states
        torques.append(s.torque)
    assert statistics.fmean(torques[150:]) == pytest.approx(torque_nm, rel=0.10)


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_python_target_example_runs_closed_loop_as_controller_external() -> None:
    """`hil run --controller external --target external` against the example in its own process over UDP."""
    host, board = _free_udp_port(), _free_udp_port()
    proc = subprocess.Popen([sys.executable, str(EXAMPLES / "python_target.py"), "--link", f"udp:{board}:{host}"])
    try:
        scenario = load_scenario("steady").with_overrides(duration_s=0.01, settle_s=0.01)
        cfg = RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=scenario, controller="external",
                        link=f"udp:{host}:{board}", target="external")
        metrics = run_closed_loop(cfg).metrics
    finally:
        proc.kill()
        proc.wait(timeout=10)
    assert metrics["controller"] == "external" and metrics["periods"] == 100
    assert metrics["torque_mean_nm"] == pytest.approx(7.0, abs=0.5)
    assert metrics["speed_mean_rpm"] == pytest.approx(1500.0, abs=15.0)


@pytest.mark.parametrize(("rpm", "torque_nm"), [(1500.0, 7.0), (-1000.0, 5.0)])
def test_python_duty_target_example_drives_the_plant_with_duty_cycles(rpm: float, torque_nm: float) -> None:
    """examples/python_duty_target.py: FOC ending in duties; its frames decode, and the plant applying the
    carrier comparison of its duties (src/pmsm_hil/hil/pwm.py, one period of delay) gives the torque asked within 2
    %."""
    from pmsm_hil.hil.pwm import applied_sequence
    motor = load_motor("niu2020-ipmsm")
    target = runpy.run_path(str(EXAMPLES / "python_duty_target.py"))["DutyTarget"]()
    _configure(target, motor)
    target.handle(Setpoint(True, int(Mode.TORQUE), torque_nm, int(ControllerId.EXTERNAL)))
    plant = Plant(motor, 100e-6, DynoMechanics(rpm))
    in_flight = Command(seq=0, states=(0,), durations_ns=(100_000,))
    torques = []
    for k in range(600):
        s = plant.sample()
        (cmd,) = target.handle(Measurement(k, s.i_a, s.i_b, s.i_c, s.theta_e, s.omega_m, s.vdc))
        assert len(cmd.duties) == 3 and all(0.0 <= d <= 1.0 for d in cmd.duties)
        plant.advance(*applied_sequence(in_flight, 100_000))
        in_flight = decode_message(FrameCodec("can").encode(cmd))  # the duties as the host receives them
        torques.append(s.torque)
    assert statistics.fmean(torques[300:]) == pytest.approx(torque_nm, rel=0.02)
