"""Small independent PMSM model for closed-loop firmware tests (Table 3 machine, midpoint steps)."""

from __future__ import annotations

import math
from dataclasses import dataclass

RS, LD, LQ, PSI_F, POLES, J = 4.5, 0.012, 0.014, 0.21, 3, 0.0013
TS = 100e-6
VDC = 300.0


def state_voltage_ab(code: int, vdc: float = VDC) -> tuple[float, float]:
    """Stator-frame voltage [V] of switching code 4·Sa+2·Sb+Sc, eq. (3) of the paper."""
    sa, sb, sc = (code >> 2) & 1, (code >> 1) & 1, code & 1
    return (2.0 / 3.0 * vdc * (sa - 0.5 * (sb + sc)), vdc / math.sqrt(3.0) * (sb - sc))


@dataclass
class DqPlant:
    """Rotor-frame currents [A], electrical angle [rad], mechanical speed [rad/s]."""

    i_d: float = 0.0
    i_q: float = 0.0
    theta: float = 0.0
    omega_m: float = 0.0
    inertia: bool = False
    load: float = 0.0  # [N·m]

    def torque(self) -> float:
        """Electromagnetic torque [N·m]."""
        return 1.5 * POLES * (PSI_F * self.i_q + (LD - LQ) * self.i_d * self.i_q)

    def phase_currents(self) -> tuple[float, float, float]:
        """Phase currents [A] (amplitude-invariant)."""
        c, s = math.cos(self.theta), math.sin(self.theta)
        al = self.i_d * c - self.i_q * s
        be = self.i_d * s + self.i_q * c
        h = 0.5 * math.sqrt(3.0) * be
        return al, -0.5 * al + h, -0.5 * al - h

    def advance(self, code: int, duration: float = TS, substeps: int = 20) -> None:
        """Hold switching code `code` for `duration` [s]."""
        ua, ub = state_voltage_ab(code)
        h = duration / substeps
        for _ in range(substeps):
            we = POLES * self.omega_m
            th = self.theta + 0.5 * we * h
            c, s = math.cos(th), math.sin(th)
            vd, vq = ua * c + ub * s, -ua * s + ub * c
            dd = (vd - RS * self.i_d + we * LQ * self.i_q) / LD
            dq = (vq - RS * self.i_q - we * LD * self.i_d - we * PSI_F) / LQ
            md, mq = self.i_d + 0.5 * h * dd, self.i_q + 0.5 * h * dq
            dd = (vd - RS * md + we * LQ * mq) / LD
            dq = (vq - RS * mq - we * LD * md - we * PSI_F) / LQ
            self.i_d += h * dd
            self.i_q += h * dq
            if self.inertia:
                self.omega_m += h * (self.torque() - self.load) / J
            self.theta = math.remainder(self.theta + we * h, 2.0 * math.pi)
