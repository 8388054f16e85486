"""The controller table's parameter masks (`ControllerInfo.params`, `hil run` refuses a `--param` outside them)
are what the controllers read: each parameter of a controller's own changes its commands at an operating point,
and no parameter outside its mask changes anything."""

from __future__ import annotations

import math

import pytest

from pmsm_hil.protocol.ids import ControllerId, ParamId
from pmsm_hil.sim_target.firmware import CONTROLLERS, MODE_TORQUE, ControllerInfo, Firmware

COMMON = next(c for c in CONTROLLERS if c.name == "mpcc").params
#: parameter -> (other parameters that make its code path run, changed value): fcs_reading flags 32 and 64 switch
#: on the fcs torque band and the flux reference; mptc3 weighs the flux only inside its torque band; im-foc
#: integrates its current errors only inside the voltage limit (a small current_kp);
#: dead-time compensation needs both dt_comp and t_dead
PROBES: dict[ParamId, tuple[dict[ParamId, float], float]] = {
    ParamId.LAMBDA: ({}, 40.0),
    ParamId.T_THR: ({}, 40e-6),
    ParamId.FLUX_REF: ({ParamId.FCS_READING: 64.0 + 11.0, ParamId.TORQUE_BAND: 100.0}, 1.0),
    ParamId.TORQUE_BAND: ({ParamId.FCS_READING: 32.0 + 11.0}, 100.0),
    ParamId.CURRENT_KP: ({}, 300.0),
    ParamId.CURRENT_KI: ({ParamId.CURRENT_KP: 5.0}, 1e3),  # a small kp keeps im-foc out of the voltage limit
    ParamId.ZERO_SELECT: ({}, 1.0),
    ParamId.DT_COMP: ({ParamId.T_DEAD: 3e-6}, 1.0),
    ParamId.T_DEAD: ({ParamId.DT_COMP: 1.0}, 3e-6),
    ParamId.FCS_READING: ({}, 5.0),
    ParamId.V3_SYMMETRIC: ({}, 1.0),
    ParamId.T_MPW: ({}, 5e-6),
    ParamId.LLS: ({}, 1e-3),
    ParamId.PWM_DUTIES: ({}, 0.0),
    ParamId.RR: ({}, 4.0),
    ParamId.LSIGMA: ({}, 0.05),
    ParamId.LM: ({}, 0.4),
    ParamId.PSI_R_REF: ({}, 0.5),
}
STEPS = 60


def _commands(info: ControllerInfo, params: dict[ParamId, float]) -> list[tuple[object, ...]]:
    """Commands of `STEPS` open-loop steps at 1000 rpm, 4 N·m, with currents of 6 A rotating with the rotor."""
    fw = Firmware()
    for pid, value in params.items():
        fw.set_param(int(pid), value)
    fw.select_controller(info.id)
    fw.set_setpoint(True, MODE_TORQUE, 4.0)
    ts, omega_m, pp = 100e-6, 1000 * 2 * math.pi / 60, 3
    out = []
    for k in range(STEPS):
        th = (pp * omega_m * k * ts) % (2 * math.pi)
        i3 = [6.0 * math.cos(th + math.pi / 2 - j * 2 * math.pi / 3) for j in range(3)]
        i6 = [*i3, *(6.0 * math.cos(th + math.pi / 2 - math.pi / 6 - j * 2 * math.pi / 3) for j in range(3))]
        cmd = fw.step(k, i6 if info.phases == 6 else i3, th, omega_m, 300.0, k * 100_000)
        out.append((cmd.states, cmd.durations_ns, cmd.mirror, cmd.status, cmd.duties))
    return out


def _changes(info: ControllerInfo, pid: ParamId) -> bool:
    context, value = PROBES[pid]
    return _commands(info, context) != _commands(info, {**context, pid: value})


@pytest.mark.parametrize("info", [c for c in CONTROLLERS if c.id != ControllerId.OFF], ids=lambda c: c.name)
def test_own_parameters_change_the_commands_and_no_other_does(info: ControllerInfo) -> None:
    assert info.params >= COMMON
    assert set(PROBES) == {p for p in ParamId if p not in COMMON}  # every parameter outside the shared step
    for pid in PROBES:
        assert _changes(info, pid) == (pid in info.params), (info.name, pid.name.lower())


def test_off_reads_no_parameter() -> None:
    assert next(c for c in CONTROLLERS if c.id == ControllerId.OFF).params == frozenset()
