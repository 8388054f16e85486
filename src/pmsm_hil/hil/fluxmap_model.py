"""The analytic saturation model the bundled flux-map preset `niu2020-ipmsm-sat` is generated from.

Model (Hinkkanen, Pescetto, Mölsä, Saarakkala, Pellegrino, Bojoi, "Sensorless self-commissioning of synchronous
reluctance motors at standstill without rotor locking", IEEE Trans. Ind. Appl. 53(3), 2017, the algebraic
inverse model i(ψ); the magnet as a constant MMF source i_f in series with the d-axis current, Awan et al.,
"Flux-linkage-based current control of saturated synchronous motors", IEEE Trans. Ind. Appl. 55(5), 2019; both as
used by motulator's saturated-machine examples):

    i_d = (a_d0 + a_dd·|ψd|^S + a_dq/(V+2)·|ψd|^U·|ψq|^(V+2))·ψd − i_f
    i_q = (a_q0 + a_qq·|ψq|^T + a_dq/(U+2)·|ψd|^(U+2)·|ψq|^V)·ψq

It is the gradient of one magnetic energy, so the map is reciprocal (∂ψd/∂iq = ∂ψq/∂id) by construction.
Parameters (this package's choice, for the 1.1-kW niu2020 machine's ratings): unsaturated Ld = 12 mH (a_d0 =
1/Ld), Lq = 16 mH (a_q0 = 1/Lq), d-axis self-saturation a_dd = 5000 Wb⁻⁵/H, S = 5 (the magnet's working point
ψf = 0.21 Wb sits on the knee: +id saturates hard), q-axis a_qq = 710 Wb⁻²/H, T = 2 (apparent Lq 16 → 13.3 mH at
the rated 7 N·m, → 8.7 mH at 30 A), cross-saturation a_dq = 2000, U = 1, V = 0; i_f such that ψd(0, 0) = 0.21 Wb.

`python -m pmsm_hil.hil.fluxmap_model --write` regenerates the preset's CSV (ψ(i) on the current grid by Newton
on the model); tests/plant/test_fluxmap.py checks the shipped file against it. Units: A, Wb, H.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import numpy as np
import numpy.typing as npt

from pmsm_hil.hil.fluxmap import FluxMap, write_csv_map

Array = npt.NDArray[np.float64]
PRESET_CSV = "niu2020-ipmsm-sat.csv"
#: the preset's grid: id, iq from −36 A to 36 A in 1.5 A steps (the 30 A trip with margin)
GRID_A = np.linspace(-36.0, 36.0, 49)


@dataclass(frozen=True, slots=True)
class SaturationModel:
    """Coefficients of the algebraic model (module docstring); psi_f [Wb] sets i_f."""

    a_d0: float = 1.0 / 0.012
    a_dd: float = 5000.0
    s: float = 5.0
    a_q0: float = 1.0 / 0.016
    a_qq: float = 710.0
    t: float = 2.0
    a_dq: float = 2000.0
    u: float = 1.0
    v: float = 0.0
    psi_f: float = 0.21

    @property
    def i_f(self) -> float:
        """The magnet's MMF as a d current [A]: i_d = 0 at ψ = (ψf, 0)."""
        return float((self.a_d0 + self.a_dd * self.psi_f**self.s) * self.psi_f)

    def currents(self, psi_d: Array, psi_q: Array) -> tuple[Array, Array, Array]:
        """(i_d, i_q) [A] and the Jacobian ∂i/∂ψ [1/H] (…, 2, 2) at fluxes [Wb]."""
        ad, aq = np.abs(psi_d), np.abs(psi_q)
        g_d = self.a_d0 + self.a_dd * ad**self.s + self.a_dq / (self.v + 2) * ad**self.u * aq ** (self.v + 2)
        g_q = self.a_q0 + self.a_qq * aq**self.t + self.a_dq / (self.u + 2) * ad ** (self.u + 2) * aq**self.v
        j = np.empty((*np.shape(psi_d), 2, 2))
        j[..., 0, 0] = g_d + self.a_dd * self.s * ad**self.s + self.a_dq / (self.v + 2) * self.u * ad**self.u * aq ** (
            self.v + 2)
        j[..., 0, 1] = self.a_dq * psi_d * ad**self.u * aq ** (self.v + 1) * np.sign(psi_q)
        j[..., 1, 0] = self.a_dq * psi_q * aq**self.v * ad ** (self.u + 1) * np.sign(psi_d)
        j[..., 1, 1] = g_q + self.a_qq * self.t * aq**self.t + self.a_dq / (self.u + 2) * self.v * ad ** (
            self.u + 2) * aq**self.v
        return g_d * psi_d - self.i_f, g_q * psi_q, j

    def flux(self, i_d: Array, i_q: Array) -> tuple[Array, Array]:
        """(ψd, ψq) [Wb] at currents [A]: Newton on `currents` from the unsaturated linear guess (to 1e-15 Wb)."""
        psi = np.stack([self.psi_f + i_d / self.a_d0, i_q / self.a_q0], axis=-1)
        for _ in range(100):
            cd, cq, j = self.currents(psi[..., 0], psi[..., 1])
            resid = np.stack([i_d - cd, i_q - cq], axis=-1)
            step = np.linalg.solve(j, resid[..., None])[..., 0]
            step = np.clip(step, -0.05, 0.05)  # damped: the d-axis knee is steep
            psi = psi + step
            if np.abs(step).max() < 1e-15:
                break
        else:
            raise RuntimeError("the saturation model's inversion did not converge")
        return psi[..., 0], psi[..., 1]

    def flux_map(self, grid: Array = GRID_A) -> FluxMap:
        """The model's map on the square grid `grid` × `grid` [A]."""
        i_d, i_q = np.meshgrid(grid, grid, indexing="ij")
        psi_d, psi_q = self.flux(i_d, i_q)
        return FluxMap(grid.copy(), grid.copy(), psi_d, psi_q, "SaturationModel")


def preset_csv_path() -> Path:
    """The bundled preset's CSV."""
    return Path(str(resources.files("pmsm_hil.hil.presets") / PRESET_CSV))


def main(argv: list[str] | None = None) -> int:
    """`--write`: regenerate the preset's CSV."""
    ap = argparse.ArgumentParser(description="the niu2020-ipmsm-sat flux map from its saturation model")
    ap.add_argument("--write", action="store_true", help=f"write presets/{PRESET_CSV}")
    args = ap.parse_args(argv)
    fmap = SaturationModel().flux_map()
    if args.write:
        write_csv_map(fmap, preset_csv_path())
        print(f"wrote {preset_csv_path()}")
    else:
        print(f"ψd(0, 0) = {fmap.psi_d[24, 24]:.6f} Wb; use --write to regenerate the preset")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
