"""The saturated PMSM of a flux map through its C kernel (src/pmsm_hil/hil/kernels/fluxmap.c) and its machine layout.

The map's axes and bicubic coefficients are cffi arrays this plant owns; the kernel's params struct points to them
(no copy, any grid size), so they live as long as the plant (and the native loop that advances it).
"""

from __future__ import annotations

from typing import Any

from pmsm_hil.hil._plant_native import lib
from pmsm_hil.hil.fluxmap_params import FluxMapParams
from pmsm_hil.hil.plant import TRACE_COLUMNS, PlantSample
from pmsm_hil.hil.plant_base import ThreePhasePlant, reset_gate_edges

#: local error tolerance per integration step, as a current [A] (docs/plant.md "Saturated PMSM")
STEP_TOLERANCE_A = 1e-9
#: margin on the largest node ‖L⁻¹‖∞ of the map: between the nodes the interpolant's may be larger
INV_L_MARGIN = 2.0


class FluxMapPlant(ThreePhasePlant):
    """Saturated PMSM + two-level inverter: flux linkage as the state, currents by the inverted map, each
    sub-interval integrated by Dormand–Prince 5(4) with error control; dead time, diode blocking and open phases as
    the PMSM kernel (fluxmap.h)."""

    KERNEL_PREFIX = "fm"
    KERNEL_TABLE = "fm_kernel"
    TRACE_COLUMNS = TRACE_COLUMNS
    _kernel_advance = staticmethod(lib.fm_advance)

    def _set_kernel_params(self, params: FluxMapParams) -> None:
        interp, checks = params.interpolant, params.checks
        ffi, p = self._ffi, self._p
        fmap = interp.fmap
        self._map_arrays = (ffi.new("double[]", fmap.id_axis.tolist()), ffi.new("double[]", fmap.iq_axis.tolist()),
                            ffi.new("double[]", interp.coef_d.ravel().tolist()),
                            ffi.new("double[]", interp.coef_q.ravel().tolist()))
        p.id_axis, p.iq_axis, p.coef_d, p.coef_q = self._map_arrays
        p.nx, p.ny = len(fmap.id_axis), len(fmap.iq_axis)
        p.rs, p.vdc = params.rs, params.vdc
        p.t_dead, p.t_mpw = params.t_dead, params.t_mpw
        p.tol_i = STEP_TOLERANCE_A
        p.inv_l_max = INV_L_MARGIN * checks.inv_l_max
        p.pole_pairs = params.pole_pairs
        self._vdc = params.vdc
        self._out = ffi.new("mk_sample_t *")
        self._psi = ffi.new("double[2]")

    def _init_kernel_state(self) -> None:
        reset_gate_edges(self._s, self.LEGS)
        self.set_state(i_d=0.0, i_q=0.0)

    def set_state(self, *, i_d: float | None = None, i_q: float | None = None, theta_e: float | None = None,
                  omega_m: float | None = None, gate: int | None = None) -> None:
        """Overwrite parts of the state: currents [A] (the flux follows from the map), angle [rad], speed [rad/s],
        applied gate code."""
        self._set_common_state(theta_e, omega_m, gate, i_d=i_d, i_q=i_q)
        lib.fm_flux(self._p, self._s.i_d, self._s.i_q, self._psi, self._psi + 1, self._ffi.NULL)
        self._s.psi_d, self._s.psi_q = self._psi[0], self._psi[1]

    @property
    def flux(self) -> tuple[float, float]:
        """(ψd, ψq) [Wb]: the state."""
        return float(self._s.psi_d), float(self._s.psi_q)

    @property
    def steps(self) -> tuple[int, int]:
        """(accepted, rejected) integration steps since the start."""
        return int(self._s.steps), int(self._s.rejected)

    def sample(self) -> Any:
        """The kernel's own sample (the C function the native loop calls)."""
        o = self._out
        lib.fm_sample(self._p, self._s, o)
        return PlantSample(int(self._s.t_ns) / 1e9, o.i[0], o.i[1], o.i[2], o.i_d, o.i_q, o.theta_e, o.omega_m,
                           o.torque, self._vdc)


__all__ = ["INV_L_MARGIN", "STEP_TOLERANCE_A", "FluxMapPlant"]
