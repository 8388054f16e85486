"""High-accuracy reference for the dual three-phase plant: scipy integration of the VSD equations."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from pmsm_hil.hil.motor_params import PmsmParams
from tests.plant.reference_solver import dq_rhs, integrate_pieces

_H3 = math.sqrt(3.0) / 2.0
#: VSD rows (alpha, beta, x, y) over phases A B C U V W, without the 1/3 factor (paper eq. (1)).
VSD_ROWS = np.array([
    [1.0, -0.5, -0.5, _H3, -_H3, 0.0],
    [0.0, _H3, -_H3, 0.5, 0.5, -1.0],
    [1.0, -0.5, -0.5, -_H3, _H3, 0.0],
    [0.0, -_H3, _H3, 0.5, 0.5, -1.0],
    [1.0, 1.0, 1.0, 0.0, 0.0, 0.0],
    [0.0, 0.0, 0.0, 1.0, 1.0, 1.0],
])
VSD = VSD_ROWS / 3.0


def code_voltage(code: int, vdc: float) -> np.ndarray:
    """(vα, vβ, vx, vy) [V] of a 6-bit code: phase-to-neutral voltages (two isolated neutrals) through VSD."""
    legs = np.array([(code >> (5 - k)) & 1 for k in range(6)], dtype=float) * vdc
    v_phase = legs.copy()
    v_phase[:3] -= legs[:3].mean()
    v_phase[3:] -= legs[3:].mean()
    return (VSD @ v_phase)[:4]


def solve_period6(p: PmsmParams, omega_m: float, theta0: float, x0: tuple[float, float, float, float],
                  states: list[int], durations_s: list[float]) -> tuple[np.ndarray, float]:
    """Integrate one period in dyno mode; returns ((i_d, i_q, i_x, i_y), theta_e) at its end."""
    w = p.pole_pairs * omega_m

    def rhs_of(st: int) -> Callable[[float, np.ndarray], list[float]]:
        va, vb, vx, vy = code_voltage(st, p.vdc)

        def rhs(t: float, y: np.ndarray) -> list[float]:
            return [*dq_rhs(p, theta0, w, va, vb, t, y), (vx - p.rs * y[2]) / p.lls, (vy - p.rs * y[3]) / p.lls]

        return rhs

    x, t_end = integrate_pieces(x0, states, durations_s, rhs_of)
    return x, theta0 + w * t_end
