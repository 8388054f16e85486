"""SyR-e flux maps (https://github.com/SyR-e/syre_public, Apache-2.0) read with scipy.io.loadmat.

Two layouts are read:
- the map file SyR-e's model manipulation saves (`fdfq_idiq_n256.mat`, `idiq_fdfq_n256.mat`): top-level matrices
  `Id`, `Iq`, `Fd`, `Fq` [A, Wb] of one meshgrid (`T` and others ignored);
- a motor-model file (`motorModel` struct, e.g. THOR.mat of SyR-e and motulator): `motorModel.FluxMap_dq` with the
  same four fields.

Axes: SyR-e writes synchronous-reluctance ("SR") axes for IPM machines — d along the highest permeance, the magnet
flux along −q — and PMSM ("PM") axes for surface and V-type machines. A motor-model file says which in
`motorModel.data.axisType`; for a bare map the rule of SyR-e's own C_MMLut.m decides: a first id column that is
negative means PM axes (the magnet on d, id ≤ 0 for field weakening), else SR axes. SR maps are turned into this
package's PMSM convention (magnet on +d) as SyR-e's MMM_sr2pm.m does: i_d = −Iq, i_q = Id, ψd = −Fq, ψq = Fd.
A map given for iq ≥ 0 only is completed by the d-axis symmetry (src/pmsm_hil/hil/fluxmap.py).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from pmsm_hil.hil.errors import InputFileError
from pmsm_hil.hil.fluxmap import FluxMap, grid_from_points

FIELDS = ("Id", "Iq", "Fd", "Fq")


def _axis_type(model: Any) -> str | None:
    """motorModel.data.axisType ('SR' or 'PM') when the file has it."""
    try:
        value = model["data"][0, 0]["axisType"][0]
    except (KeyError, ValueError, IndexError, TypeError):
        return None
    text = str(value).strip()
    return text if text in ("SR", "PM") else None


def _fields(mat: dict[str, Any], path: Path) -> tuple[dict[str, np.ndarray], str | None]:
    if all(k in mat for k in FIELDS):
        return {k: np.asarray(mat[k], dtype=float) for k in FIELDS}, None
    if "motorModel" in mat:
        try:
            model = mat["motorModel"][0, 0]
            fm = model["FluxMap_dq"][0, 0]
            return {k: np.asarray(fm[k], dtype=float) for k in FIELDS}, _axis_type(model)
        except (KeyError, ValueError, IndexError):
            raise InputFileError(f"flux map {path}: motorModel has no FluxMap_dq with Id, Iq, Fd, Fq") from None
    raise InputFileError(f"flux map {path}: no SyR-e flux map (variables Id, Iq, Fd, Fq or motorModel.FluxMap_dq); "
                         f"found {', '.join(k for k in mat if not k.startswith('__')) or 'nothing'}")


def read_syre_mat(path: Path) -> FluxMap:
    """A map from a SyR-e .mat file, in PMSM axes (see the module docstring). Needs scipy (the `fluxmap` extra)."""
    try:
        from scipy.io import loadmat
    except ImportError:
        raise InputFileError(f"flux map {path}: reading .mat needs scipy (pip install 'pmsm-hil[fluxmap]')") from None
    try:
        mat = loadmat(str(path))
    except (OSError, ValueError, NotImplementedError) as exc:
        raise InputFileError(f"flux map {path}: not a readable MATLAB file ({exc})") from None
    f, axis_type = _fields(mat, path)
    shapes = {k: v.shape for k, v in f.items()}
    if len(set(shapes.values())) != 1:
        raise InputFileError(f"flux map {path}: Id, Iq, Fd, Fq differ in shape ({shapes})")
    i_d, i_q, f_d, f_q = (f[k].ravel() for k in FIELDS)
    pm_axes = axis_type == "PM" if axis_type is not None else float(np.sum(f["Id"][:, 0])) < 0.0
    if pm_axes:
        return grid_from_points(i_d, i_q, f_d, f_q, str(path))
    return grid_from_points(-i_q, i_d, -f_q, f_d, str(path))


__all__ = ["FIELDS", "read_syre_mat"]
