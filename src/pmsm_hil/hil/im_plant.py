"""Python API of the exact induction machine + inverter plant (kernel src/pmsm_hil/hil/kernels/im.c), and its machine
kind "im" (the `MachineLayout` registered by pmsm_hil.hil.machine).

Samples carry the phase currents, the currents in the rotor-flux frame (i_d: flux-producing, along ψR; i_q:
torque-producing), the rotor's electrical angle θe = n_p·θm, the speed and the torque; `psi_r` gives the rotor
flux itself. Units: SI (A, Wb, rad, rad/s, N·m, s).
"""

from __future__ import annotations

from pmsm_hil.hil._plant_native import lib
from pmsm_hil.hil.im_params import ImParams
from pmsm_hil.hil.machine import MEAS_THREE, THREE_PHASE, MachineLayout, register_layout
from pmsm_hil.hil.plant import TRACE_COLUMNS, PlantSample
from pmsm_hil.hil.plant_base import ThreePhasePlant, reset_gate_edges

__all__ = ["INDUCTION", "ImPlant"]


class ImPlant(ThreePhasePlant):
    """Exact squirrel-cage induction machine (inverse-Γ model) + two-level inverter, one control period at a
    time: closed-form solution of each constant-voltage sub-interval at constant speed (docs/plant.md). The
    state starts at zero flux."""

    KERNEL_PREFIX = "im"
    KERNEL_TABLE = "im_kernel"
    TRACE_COLUMNS = TRACE_COLUMNS
    _kernel_advance = staticmethod(lib.im_advance)

    def _set_kernel_params(self, params: ImParams) -> None:
        p = self._p
        p.rs, p.rr, p.lsigma, p.lm, p.vdc = params.rs, params.rr, params.lsigma, params.lm, params.vdc
        p.t_dead, p.t_mpw = params.t_dead, params.t_mpw
        p.pole_pairs = params.pole_pairs
        self._out = self._ffi.new("mk_sample_t *")

    def _init_kernel_state(self) -> None:
        reset_gate_edges(self._s, self.LEGS)

    def set_state(self, *, psi_s: tuple[float, float] | None = None, psi_r: tuple[float, float] | None = None,
                  theta_e: float | None = None, omega_m: float | None = None, gate: int | None = None) -> None:
        """Overwrite parts of the state: stator and rotor flux in the stator frame (α, β) [Wb], rotor angle
        [rad], speed [rad/s], applied gate code."""
        self._set_common_state(theta_e, omega_m, gate)
        for name, value in (("psi_s", psi_s), ("psi_r", psi_r)):
            if value is not None:
                arr = getattr(self._s, name)
                arr[0], arr[1] = float(value[0]), float(value[1])

    @property
    def psi_r(self) -> tuple[float, float]:
        """Rotor flux ψR in the stator frame (α, β) [Wb]."""
        return (self._s.psi_r[0], self._s.psi_r[1])

    @property
    def psi_s(self) -> tuple[float, float]:
        """Stator flux ψs in the stator frame (α, β) [Wb]."""
        return (self._s.psi_s[0], self._s.psi_s[1])

    def sample(self) -> PlantSample:
        """The kernel's own sample (the same C function the native loop calls)."""
        o = self._out
        lib.im_sample(self._p, self._s, o)
        return PlantSample(int(self._s.t_ns) / 1e9, o.i[0], o.i[1], o.i[2], o.i_d, o.i_q, o.theta_e, o.omega_m,
                           o.torque, self._p.vdc)


#: The induction machine kind: three legs, the three-phase Measurement and replay layouts.
INDUCTION = MachineLayout(
    kind="im", plant_class=ImPlant, params_class=ImParams, accepts=lambda p: True, measurement=MEAS_THREE,
    measure=THREE_PHASE.measure, replay_legs=THREE_PHASE.replay_legs, replay_columns=THREE_PHASE.replay_columns,
    replay_row=THREE_PHASE.replay_row, target_extras=THREE_PHASE.target_extras)
register_layout(INDUCTION)
