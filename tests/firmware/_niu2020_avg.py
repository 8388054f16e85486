"""An average-value d/q model of the niu2020 IPMSM (Table 3) driven by three leg duty cycles, for closed-loop tests
of a firmware's control timing (no switching ripple, no dead time): independent of the firmware's own math."""

from __future__ import annotations

import math
from dataclasses import dataclass

RS, LD, LQ, PSI_F, PP, J = 4.5, 0.012, 0.014, 0.21, 3, 0.0013
VDC = 311.0
SQRT3 = math.sqrt(3.0)


@dataclass
class AvgPlant:
    """Rotor-frame currents [A], mechanical angle [rad] and speed [rad/s], load torque [N·m]."""

    i_d: float = 0.0
    i_q: float = 0.0
    theta_m: float = 0.0
    omega_m: float = 0.0
    load: float = 0.0

    def torque(self) -> float:
        """Electromagnetic torque [N·m]."""
        return 1.5 * PP * (PSI_F * self.i_q + (LD - LQ) * self.i_d * self.i_q)

    def phase_ab(self) -> tuple[float, float]:
        """Phase currents a and b [A] (amplitude-invariant; c = −a − b)."""
        th = PP * self.theta_m
        c, s = math.cos(th), math.sin(th)
        alpha = self.i_d * c - self.i_q * s
        beta = self.i_d * s + self.i_q * c
        return alpha, -0.5 * alpha + 0.5 * SQRT3 * beta

    def advance(self, v_alpha: float, v_beta: float, dt: float, *, conducting: bool = True, substeps: int = 4) -> None:
        """Hold the stator voltage (v_alpha, v_beta) [V] for dt [s] (forward Euler substeps); an inverter that
        does not conduct (outputs off, back EMF below the DC link) holds the currents at zero."""
        h = dt / substeps
        for _ in range(substeps):
            if conducting:
                th = PP * self.theta_m
                c, s = math.cos(th), math.sin(th)
                vd, vq = v_alpha * c + v_beta * s, -v_alpha * s + v_beta * c
                we = PP * self.omega_m
                did = (vd - RS * self.i_d + we * LQ * self.i_q) / LD
                diq = (vq - RS * self.i_q - we * LD * self.i_d - we * PSI_F) / LQ
                self.i_d += h * did
                self.i_q += h * diq
            else:
                self.i_d = self.i_q = 0.0
            self.omega_m += h * (self.torque() - self.load) / J
            self.theta_m += h * self.omega_m


def duties_to_alpha_beta(d: list[float] | tuple[float, ...], vdc: float = VDC) -> tuple[float, float]:
    """The mean stator voltage [V] of three leg duty cycles on vdc (the common mode drops out)."""
    return vdc * (2 * d[0] - d[1] - d[2]) / 3.0, vdc * (d[1] - d[2]) / SQRT3
