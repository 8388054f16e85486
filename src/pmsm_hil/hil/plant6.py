"""Python API of the exact dual three-phase PMSM + six-leg inverter plant (kernel src/pmsm_hil/hil/kernels/plant6.c).

Same method names as `pmsm_hil.hil.plant.Plant`; states are 6-bit codes [S_A S_B S_C S_U S_V S_W]
(S_A the most significant bit, e.g. V13 = 0b001101). Phases A, B, C sit at 0°, 120°, 240° and U, V, W
at 30°, 150°, 270°; the x-y currents are in the stationary frame (docs/plant.md, "Dual three-phase").
"""

from __future__ import annotations

from typing import NamedTuple

from pmsm_hil.hil._plant_native import ffi, lib
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.mechanics import Mechanics
from pmsm_hil.hil.motor_params import PmsmParams
from pmsm_hil.hil.plant_base import PlantBase, reset_gate_edges, set_inverter_pmsm_params

#: Trace columns of `Plant6.last_trace`: t [s], six phase currents [A], torque [N·m], omega_m [rad/s],
#: x-y currents [A].
TRACE_COLUMNS6 = ("t", "i_a", "i_b", "i_c", "i_u", "i_v", "i_w", "torque", "omega_m", "i_x", "i_y")
N_LEGS = 6
MAX_STATE6 = 63


class PlantSample6(NamedTuple):
    """Dual three-phase plant state at a period start.

    t [s]; i_a, i_b, i_c (set 1), i_u, i_v, i_w (set 2), i_d, i_q, i_x, i_y [A]; theta_e [rad];
    omega_m [rad/s]; torque [N·m]; vdc [V].
    """

    t: float
    i_a: float
    i_b: float
    i_c: float
    i_u: float
    i_v: float
    i_w: float
    i_d: float
    i_q: float
    i_x: float
    i_y: float
    theta_e: float
    omega_m: float
    torque: float
    vdc: float

    @property
    def phase_currents(self) -> tuple[float, float, float, float, float, float]:
        """(i_a, i_b, i_c, i_u, i_v, i_w) [A]."""
        return (self.i_a, self.i_b, self.i_c, self.i_u, self.i_v, self.i_w)


class Plant6(PlantBase):
    """Exact dual three-phase PMSM (VSD model) + six-leg two-level inverter, one period at a time.

    The dq subspace is solved in closed form with the stator-frame voltage constant per sub-interval
    (as `Plant`); the x-y subspace (R, L_ls, stationary frame) is a first-order exponential. Dead time
    uses the sign rule per leg (diode by the phase-current sign at the edge, held for t_dead); the
    three-phase open-phase model is not implemented for six phases.
    """

    KERNEL_PREFIX = "p6"
    KERNEL_TABLE = "p6_kernel"
    LEGS = N_LEGS
    MAX_STATE = MAX_STATE6
    STATE_FORMAT = "[S_A S_B S_C S_U S_V S_W]"
    TRACE_COLUMNS = TRACE_COLUMNS6
    _kernel_advance = staticmethod(lib.p6_advance)

    def __init__(self, params: PmsmParams, ts_s: float, mechanics: Mechanics, *, theta0_rad: float = 0.0,
                 trace_dt_s: float | None = 2e-6, max_piece_s: float = 5e-6) -> None:
        if not params.lls > 0.0:
            raise ParameterError(f"motor parameter 'lls' must be > 0 H for a six-phase plant, got {params.lls}")
        super().__init__(params, ts_s, mechanics, theta0_rad=theta0_rad, trace_dt_s=trace_dt_s,
                         max_piece_s=max_piece_s)
        self._phase = ffi.new("double[]", N_LEGS)

    def _set_kernel_params(self, params: PmsmParams) -> None:
        set_inverter_pmsm_params(self._p, params)
        self._p.lls = params.lls

    def _init_kernel_state(self) -> None:
        reset_gate_edges(self._s, self.LEGS)

    def set_state(self, *, i_d: float | None = None, i_q: float | None = None, i_x: float | None = None,
                  i_y: float | None = None, theta_e: float | None = None, omega_m: float | None = None,
                  gate: int | None = None) -> None:
        """Overwrite parts of the state: currents [A], angle [rad], speed [rad/s], applied 6-bit gate code."""
        self._set_common_state(theta_e, omega_m, gate, i_d=i_d, i_q=i_q, i_x=i_x, i_y=i_y)

    def sample(self) -> PlantSample6:
        """Exact state at the current time (the period start)."""
        s = self._s
        ph = self._phase
        lib.p6_phase_currents(s.i_d, s.i_q, s.theta_e, s.i_x, s.i_y, ph)
        return PlantSample6(int(s.t_ns) / 1e9, ph[0], ph[1], ph[2], ph[3], ph[4], ph[5], s.i_d, s.i_q, s.i_x,
                            s.i_y, s.theta_e, self._mech_s.omega_m, lib.p6_torque(self._p, s.i_d, s.i_q), self._p.vdc)
