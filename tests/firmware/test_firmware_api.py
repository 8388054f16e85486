"""Python-level tests of the firmware wrapper (cffi): configuration errors, commands, closed loops."""

from __future__ import annotations

import math
import statistics
from typing import Any

import pytest

from pmsm_hil.sim_target.firmware import (
    CONTROLLER_IDS,
    CONTROLLERS,
    MODE_SPEED,
    MODE_TORQUE,
    PARAM_IDS,
    Firmware,
    FirmwareCommand,
    FirmwareConfigError,
    FirmwareInputError,
)
from tests.firmware._dq_plant import DqPlant

TORQUE_PER_AMP = 1.5 * 3 * 0.21  # [N·m/A], id = 0


def _mpcc_torque(torque: float) -> Firmware:
    fw = Firmware()
    fw.select_controller(CONTROLLER_IDS["mpcc"])
    fw.set_setpoint(True, MODE_TORQUE, torque)
    return fw


def test_param_errors_name_the_param() -> None:
    fw = Firmware()
    with pytest.raises(FirmwareConfigError, match="ld"):
        fw.set_param(PARAM_IDS["ld"], -1e-3)
    with pytest.raises(FirmwareConfigError, match="ts"):
        fw.set_param(PARAM_IDS["ts"], 0.0)
    with pytest.raises(FirmwareConfigError, match="param_id 99"):
        fw.set_param(99, 1.0)
    with pytest.raises(FirmwareConfigError, match="param_id 300"):
        fw.set_param(300, 1.0)
    with pytest.raises(FirmwareConfigError, match="speed_kp"):
        fw.set_param(PARAM_IDS["speed_kp"], float("nan"))
    with pytest.raises(FirmwareConfigError, match="rs"):
        not_a_number: Any = "abc"
        fw.set_param(PARAM_IDS["rs"], not_a_number)
    assert fw.get_param(PARAM_IDS["ld"]) == pytest.approx(0.012)
    fw.set_param(PARAM_IDS["ld"], 0.02)
    assert fw.get_param(PARAM_IDS["ld"]) == pytest.approx(0.02)


def test_controller_selection_errors() -> None:
    fw = Firmware()
    fw.select_controller(CONTROLLER_IDS["mpcc"])
    missing = [c.id for c in CONTROLLERS if not Firmware.controller_implemented(c.id)]
    for cid in missing:
        with pytest.raises(FirmwareConfigError, match="not implemented"):
            fw.select_controller(cid)
    with pytest.raises(FirmwareConfigError, match="controller_id 255: unknown controller id"):
        fw.select_controller(CONTROLLER_IDS["external"])  # reserved for foreign firmware: not in the table
    with pytest.raises(FirmwareConfigError, match="unknown controller"):
        fw.select_controller(max(c.id for c in CONTROLLERS) + 1)  # first id past the firmware's table
    with pytest.raises(FirmwareConfigError, match="controller_id -1"):
        fw.select_controller(-1)
    assert fw.controller_id == CONTROLLER_IDS["mpcc"]
    assert Firmware.controller_implemented(1) and Firmware.controller_implemented(6)
    assert not Firmware.controller_implemented(200)


def test_setpoint_errors() -> None:
    fw = Firmware()
    with pytest.raises(FirmwareConfigError, match="mode 3"):
        fw.set_setpoint(True, 3, 1.0)
    with pytest.raises(FirmwareConfigError, match="reference inf"):
        fw.set_setpoint(True, MODE_SPEED, math.inf)
    assert not fw.enabled
    fw.set_setpoint(True, MODE_SPEED, 10.0)
    assert fw.enabled


def test_step_command_fields() -> None:
    fw = _mpcc_torque(5.0)
    cmd = fw.step(7, (0.0, 0.0, 0.0), -math.pi / 6, 0.0, 300.0, 0)
    assert isinstance(cmd, FirmwareCommand)
    assert cmd.seq == 7
    assert cmd.states == (6,) and cmd.vector_id == 2  # +q at 60 degrees: V2 = 110
    assert cmd.durations_ns == (100_000,)
    assert cmd.candidates == 7 and cmd.status == 0
    assert cmd.exec_time_ns == sum(cmd.split_ns) and cmd.exec_time_ns > 0
    assert cmd.torque_ref == pytest.approx(5.0)
    assert cmd.iq_ref == pytest.approx(5.0 / TORQUE_PER_AMP, rel=1e-6)
    assert cmd.id_ref == 0.0


def test_step_rejects_malformed_input() -> None:
    fw = _mpcc_torque(1.0)
    with pytest.raises(FirmwareInputError, match="i_abc"):
        fw.step(0, (0.0, 0.0), 0.0, 0.0, 300.0, 0)
    with pytest.raises(FirmwareInputError, match="seq"):
        fw.step(70_000, (0.0, 0.0, 0.0), 0.0, 0.0, 300.0, 0)
    with pytest.raises(FirmwareInputError, match="t_ns"):
        fw.step(0, (0.0, 0.0, 0.0), 0.0, 0.0, 300.0, -5)
    with pytest.raises(FirmwareInputError, match="theta_e"):
        not_an_angle: Any = "x"
        fw.step(0, (0.0, 0.0, 0.0), not_an_angle, 0.0, 300.0, 0)
    # Non-finite measurements are a bad frame, answered with a zero vector, not an exception.
    cmd = fw.step(1, (math.nan, 0.0, 0.0), 0.0, 0.0, 300.0, 100_000)
    assert cmd.status == 4 and cmd.vector_id in (0, 7)
    # Six-phase frames reach the firmware, which has no six-phase controller yet.
    cmd = fw.step(2, (0.0,) * 6, 0.0, 0.0, 300.0, 200_000)
    assert cmd.status == 5


def test_durations_follow_ts() -> None:
    fw = _mpcc_torque(2.0)
    fw.set_param(PARAM_IDS["ts"], 50e-6)
    cmd = fw.step(0, (1.0, -0.5, -0.5), 0.3, 20.0, 300.0, 0)
    assert sum(cmd.durations_ns) == 50_000


def test_current_loop_tracks_torque_reference() -> None:
    """MPCC with the plant applying command k over [k+1, k+2): mean i_q on its reference."""
    fw = _mpcc_torque(4.0)
    plant = DqPlant(omega_m=120.0)
    applied = 0
    iq: list[float] = []
    for k in range(1500):
        cmd = fw.step(k, plant.phase_currents(), plant.theta, plant.omega_m, 300.0, k * 100_000)
        plant.advance(applied)
        applied = cmd.states[0]
        if k >= 500:
            iq.append(plant.i_q)
    assert statistics.fmean(iq) == pytest.approx(4.0 / TORQUE_PER_AMP, abs=0.3)
    assert statistics.pstdev(iq) < 1.0


def test_speed_loop_droop_recovers_with_the_paper_gains() -> None:
    """Load step at speed: droop ≈ T_L/kp at once, then recovery with time constant kp/ki ≈ 2.3 s."""
    fw = Firmware()
    fw.select_controller(CONTROLLER_IDS["mpcc"])
    load = 2.0
    fw.set_param(PARAM_IDS["torque_integrator_init"], load)  # bumpless start at the operating point
    fw.set_setpoint(True, MODE_SPEED, 100.0)
    plant = DqPlant(omega_m=100.0, i_q=load / TORQUE_PER_AMP, inertia=True, load=load)
    applied = 0
    errors: list[float] = []
    for k in range(4000):
        if k == 500:
            plant.load = 2.0 * load  # +2 N·m load step at t = 50 ms
        cmd = fw.step(k & 0xFFFF, plant.phase_currents(), plant.theta, plant.omega_m, 300.0, k * 100_000)
        plant.advance(applied, substeps=8)
        applied = cmd.states[0]
        errors.append(100.0 - plant.omega_m)
    before = statistics.fmean(errors[300:500])
    assert abs(before) < 0.3  # preset integrator: no start-up transient
    droop = load / 0.8  # [rad/s]: proportional action alone balances the step
    early = statistics.fmean(errors[900:1100])  # ~50 ms after the step
    late = statistics.fmean(errors[3800:4000])  # ~0.34 s after the step
    tau = 0.8 / 0.35  # [s]
    assert early == pytest.approx(droop * math.exp(-0.05 / tau), rel=0.05)
    assert late == pytest.approx(droop * math.exp(-0.34 / tau), rel=0.05)
    assert late / early == pytest.approx(math.exp(-0.29 / tau), abs=0.03)
