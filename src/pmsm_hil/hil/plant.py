"""Python API of the exact PMSM + inverter plant (compiled kernel in src/pmsm_hil/hil/kernels/plant.c)."""

from __future__ import annotations

import math
from typing import NamedTuple

from pmsm_hil.hil._plant_native import lib
from pmsm_hil.hil.motor_params import PmsmParams
from pmsm_hil.hil.plant_base import (
    MAX_SUBINTERVALS,
    PeriodStats,
    ThreePhasePlant,
    reset_gate_edges,
    set_inverter_pmsm_params,
)

__all__ = ["MAX_SUBINTERVALS", "TRACE_COLUMNS", "PeriodStats", "Plant", "PlantSample"]

TRACE_COLUMNS = ("t", "i_a", "i_b", "i_c", "torque", "omega_m")
_SQRT3_2 = math.sqrt(3.0) / 2.0


class PlantSample(NamedTuple):
    """Plant state sampled at a period start (synchronous sampling).

    t [s]; i_a, i_b, i_c, i_d, i_q [A]; theta_e [rad]; omega_m [rad/s]; torque [N·m]; vdc [V].
    """

    t: float
    i_a: float
    i_b: float
    i_c: float
    i_d: float
    i_q: float
    theta_e: float
    omega_m: float
    torque: float
    vdc: float

    @property
    def phase_currents(self) -> tuple[float, float, float]:
        """(i_a, i_b, i_c) [A]."""
        return (self.i_a, self.i_b, self.i_c)


class Plant(ThreePhasePlant):
    """Exact three-phase PMSM + two-level inverter advanced one control period at a time.

    Each sub-interval's voltage is constant in the stator frame; with the speed constant over a
    sub-interval (dyno mode) the rotor-frame solution is exact (closed form). In inertia mode the
    speed is updated every ``max_piece_s`` from the trapezoidal torque integral.
    """

    KERNEL_PREFIX = "pl"
    KERNEL_TABLE = "pl_kernel"
    TRACE_COLUMNS = TRACE_COLUMNS
    _kernel_advance = staticmethod(lib.pl_advance)

    def _set_kernel_params(self, params: PmsmParams) -> None:
        set_inverter_pmsm_params(self._p, params)
        self._torque_k = 1.5 * params.pole_pairs
        self._psi_f = params.psi_f
        self._dl = params.ld - params.lq
        self._vdc = params.vdc

    def _init_kernel_state(self) -> None:
        reset_gate_edges(self._s, self.LEGS)

    def set_state(self, *, i_d: float | None = None, i_q: float | None = None,
                  theta_e: float | None = None, omega_m: float | None = None, gate: int | None = None) -> None:
        """Overwrite parts of the state: currents [A], angle [rad], speed [rad/s], applied gate code."""
        self._set_common_state(theta_e, omega_m, gate, i_d=i_d, i_q=i_q)

    def sample(self) -> PlantSample:
        """Exact state at the current time (the period start)."""
        s = self._s
        i_d, i_q, th = s.i_d, s.i_q, s.theta_e
        c, sn = math.cos(th), math.sin(th)
        i_al = i_d * c - i_q * sn
        i_be = i_d * sn + i_q * c
        return PlantSample(int(s.t_ns) / 1e9, i_al, -0.5 * i_al + _SQRT3_2 * i_be, -0.5 * i_al - _SQRT3_2 * i_be,
                           i_d, i_q, th, self._mech_s.omega_m, self._torque_k * (self._psi_f + self._dl * i_d) * i_q,
                           self._vdc)
