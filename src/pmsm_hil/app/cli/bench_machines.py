"""Operating points of `hil bench controllers`: the machine each controller is timed on and its inputs.

Three-phase controllers run on the firmware's default machine (Table 3 of 000_81a00a8e308450c6.txt,
p = 3) at 1500 rpm with rated q current 7.4 A. The dual three-phase controllers (mptc1..3) refuse
three-phase frames, so they run on the `zhang2021-dtpmsm` preset (p = 4, parameters written to the
firmware) at 1500 rpm with the q current of 40 N·m, six phase currents by the inverse VSD.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from pmsm_hil.hil.presets_loader import load_pmsm
from pmsm_hil.protocol.ids import ParamId
from pmsm_hil.sim_target.firmware import CONTROLLERS

TS = 100e-6  # [s]
OMEGA_M = 1500.0 * 2.0 * math.pi / 60.0  # [rad/s]
#: phase axes [rad]: A, B, C (three-phase); A, B, C, U, V, W (dual three-phase, 30° apart)
ANGLES_3 = (0.0, 2.0 * math.pi / 3.0, 4.0 * math.pi / 3.0)
ANGLES_6 = (*ANGLES_3, math.pi / 6.0, 5.0 * math.pi / 6.0, 3.0 * math.pi / 2.0)
#: the firmware's dual three-phase controllers (phase count of its controller table)
SIX_PHASE_IDS = frozenset(c.id for c in CONTROLLERS if c.phases == 6)


@dataclass(frozen=True, slots=True)
class BenchMachine:
    """Machine of a timing run: pole pairs, q current [A], phase axes [rad] and firmware parameters."""

    name: str
    pole_pairs: int
    i_q: float
    angles: tuple[float, ...]
    params: dict[int, float] = field(default_factory=dict)

    @property
    def we_ts(self) -> float:
        """Electrical angle advanced per period [rad]."""
        return self.pole_pairs * OMEGA_M * TS


THREE_PHASE = BenchMachine("firmware default (niu2020 Table 3), 1500 rpm, i_q 7.4 A", 3, 7.4, ANGLES_3)


def six_phase_machine() -> BenchMachine:
    """zhang2021-dtpmsm at 1500 rpm and 40 N·m (i_q = T / (3 p ψf))."""
    m = load_pmsm("zhang2021-dtpmsm")
    params = {int(ParamId.RS): m.rs, int(ParamId.LD): m.ld, int(ParamId.LQ): m.lq, int(ParamId.PSI_F): m.psi_f,
              int(ParamId.POLE_PAIRS): float(m.pole_pairs), int(ParamId.VDC): m.vdc, int(ParamId.LLS): m.lls,
              int(ParamId.TORQUE_LIMIT): 1.2 * m.rated_torque_nm}
    i_q = 40.0 / (3.0 * m.pole_pairs * m.psi_f)
    return BenchMachine("zhang2021-dtpmsm, 1500 rpm, 40 N·m", m.pole_pairs, i_q, ANGLES_6, params)


def machine_for(controller_id: int) -> BenchMachine:
    """The bench machine of a controller id."""
    return six_phase_machine() if controller_id in SIX_PHASE_IDS else THREE_PHASE


def inputs(machine: BenchMachine, steps: int) -> list[tuple[tuple[float, ...], float]]:
    """(phase currents [A], theta_e [rad]) of a q-axis current vector rotating at 1500 rpm."""
    rows = []
    for k in range(steps):
        th = machine.we_ts * k
        al, be = -machine.i_q * math.sin(th), machine.i_q * math.cos(th)
        rows.append((tuple(al * math.cos(a) + be * math.sin(a) for a in machine.angles),
                     math.remainder(th, 2.0 * math.pi)))
    return rows
