"""High-accuracy reference: the same PMSM equations integrated by scipy with stator-frame voltage."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator, Sequence
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from pmsm_hil.hil.motor_params import PmsmParams


def rows_and_references(rows: np.ndarray, t0: float, reference: Callable[[int], Any]) -> Iterator[tuple[Any, Any]]:
    """Trace rows at least 1 µs (the shortest plant period) after `t0` [s], each with `reference(offset_ns)`: the
    sample of a second plant whose period ends at the row's time."""
    for row in rows:
        offset_ns = round((row[0] - t0) * 1e9)
        if offset_ns >= 1000:
            yield row, reference(offset_ns)


def stator_voltage(state: int, vdc: float) -> tuple[float, float]:
    """(vα, vβ) [V] of a three-phase state code 4·Sa + 2·Sb + Sc."""
    sa, sb, sc = (state >> 2) & 1, (state >> 1) & 1, state & 1
    return vdc / 3.0 * (2 * sa - sb - sc), vdc / math.sqrt(3.0) * (sb - sc)


def dq_rhs(p: PmsmParams, theta0: float, w: float, va: float, vb: float, t: float, y: np.ndarray) -> list[float]:
    """d/dt (i_d, i_q) [A/s] at time `t` [s] of a stator-frame voltage (va, vb) [V], rotor at electrical speed `w`
    [rad/s] from angle `theta0` [rad]."""
    th = theta0 + w * t
    vd = va * math.cos(th) + vb * math.sin(th)
    vq = -va * math.sin(th) + vb * math.cos(th)
    return [(vd - p.rs * y[0] + w * p.lq * y[1]) / p.ld,
            (vq - p.rs * y[1] - w * p.ld * y[0] - w * p.psi_f) / p.lq]


def integrate_pieces(x0: Sequence[float], states: list[int], durations_s: list[float],
                     rhs_of: Callable[[int], Callable[[float, np.ndarray], list[float]]]) -> tuple[np.ndarray, float]:
    """Integrate `x0` through the pieces (state code, duration [s]) with `rhs_of(state)` as the right-hand side;
    returns the state at the end and the time integrated [s]."""
    x = np.array(x0, dtype=float)
    t0 = 0.0
    for st, du in zip(states, durations_s, strict=True):
        if du <= 0:
            continue
        sol = solve_ivp(rhs_of(st), (t0, t0 + du), x, method="DOP853", rtol=1e-11, atol=1e-12)
        x = sol.y[:, -1]
        t0 += du
    return x, t0


def solve_period(p: PmsmParams, omega_m: float, theta0: float, i_dq: tuple[float, float],
                 states: list[int], durations_s: list[float]) -> tuple[float, float, float]:
    """Integrate one period in dyno mode; returns (i_d, i_q, theta_e) at its end."""
    w = p.pole_pairs * omega_m

    def rhs_of(st: int) -> Callable[[float, np.ndarray], list[float]]:
        va, vb = stator_voltage(st, p.vdc)
        return lambda t, y: dq_rhs(p, theta0, w, va, vb, t, y)

    x, t_end = integrate_pieces(i_dq, states, durations_s, rhs_of)
    return float(x[0]), float(x[1]), theta0 + w * t_end
