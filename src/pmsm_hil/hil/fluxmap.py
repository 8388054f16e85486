"""Flux maps of a saturated PMSM: ψd(id, iq), ψq(id, iq) on a rectangular current grid (kind "pmsm-fluxmap").

Read from a CSV (`id,iq,psi_d,psi_q` in A and Wb, one row per grid point, any order) or a SyR-e `.mat` file
(`fluxmap_syre.py`); a map given for iq ≥ 0 only is completed by the machine's symmetry about the d axis,
ψd(id, −iq) = ψd(id, iq), ψq(id, −iq) = −ψq(id, iq).

The interpolant (what the C kernel evaluates, src/pmsm_hil/hil/kernels/fluxmap.c): piecewise bicubic Hermite on the grid
cells, C1 everywhere, with node slopes ∂ψ/∂id, ∂ψ/∂iq by PCHIP (Fritsch–Carlson/Butland weighted harmonic mean of
the neighbouring secants, as scipy's PchipInterpolator) along each grid line and the twist ∂²ψ/∂id∂iq by PCHIP of
the id-slopes along iq. PCHIP keeps every grid line's monotonicity (no overshoot between points, so ψd stays
increasing in id and ψq in iq along the lines the map was measured on) and reproduces an affine map exactly (a
linear machine's map is interpolated without error). Outside the grid: first-order continuation from the nearest
grid point. The load checks (`check_map`): strictly increasing ψd along id and ψq along iq (else the inverse map
i(ψ) is not unique), a positive incremental-inductance determinant at every node, and the reciprocity residual
|∂ψd/∂iq − ∂ψq/∂id| (a lossless magnetic field has a co-energy whose gradient is ψ, so the residual is 0; a
measured or FEA map shows its noise there: reported, not refused).

Units: A, Wb, H (incremental inductances ∂ψ/∂i), 1/H.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
import numpy.typing as npt

from pmsm_hil.hil.errors import InputFileError

Array = npt.NDArray[np.float64]
CSV_COLUMNS = ("id", "iq", "psi_d", "psi_q")

#: the Hermite basis: a = M F Mᵀ gives the coefficients a[m, n] of u^m v^n from the corner data F
_M = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [-3.0, 3.0, -2.0, -1.0], [2.0, -2.0, 1.0, 1.0]])


@dataclass(frozen=True, eq=False)
class FluxMap:
    """A flux map on a rectangular grid: `id_axis` (nx,), `iq_axis` (ny,) ascending [A]; `psi_d`, `psi_q` (nx, ny)
    [Wb] with [k, l] at (id_axis[k], iq_axis[l]); `source` names the file; `mirrored` says the iq < 0 half was
    completed by symmetry."""

    id_axis: Array
    iq_axis: Array
    psi_d: Array
    psi_q: Array
    source: str
    mirrored: bool = False


def pchip_slopes(x: Array, y: Array) -> Array:
    """Node derivatives of the monotone piecewise cubic Hermite interpolant of y(x) along axis 0 of y (x ascending,
    ≥ 2 points): weighted harmonic mean of the secants, 0 where they change sign, one-sided three-point ends limited
    to keep the shape (Fritsch & Carlson 1980, Fritsch & Butland 1984; scipy.interpolate.PchipInterpolator)."""
    h = np.diff(x).reshape((-1,) + (1,) * (y.ndim - 1))
    delta = np.diff(y, axis=0) / h
    d = np.zeros_like(y)
    if len(x) == 2:
        d[0] = d[1] = delta[0]
        return d
    h0, h1 = h[:-1], h[1:]
    w1, w2 = 2.0 * h1 + h0, h1 + 2.0 * h0
    same = (np.sign(delta[:-1]) * np.sign(delta[1:])) > 0
    with np.errstate(divide="ignore", invalid="ignore"):
        harmonic = (w1 + w2) / (w1 / delta[:-1] + w2 / delta[1:])
    d[1:-1] = np.where(same, harmonic, 0.0)

    def end(h_a: Array, h_b: Array, m_a: Array, m_b: Array) -> Array:
        e = ((2.0 * h_a + h_b) * m_a - h_a * m_b) / (h_a + h_b)
        e = np.where(np.sign(e) != np.sign(m_a), 0.0, e)
        return np.where((np.sign(m_a) != np.sign(m_b)) & (np.abs(e) > np.abs(3.0 * m_a)), 3.0 * m_a, e)

    d[0] = end(h[0], h[1], delta[0], delta[1])
    d[-1] = end(h[-1], h[-2], delta[-1], delta[-2])
    return d


@dataclass(frozen=True, eq=False)
class Interpolant:
    """Node slopes and per-cell bicubic coefficients of one map: `coef_d`, `coef_q` ((nx−1)·(ny−1), 16), cell
    index ix·(ny−1) + iy, coefficient 4·m + n of u^m·v^n (u, v ∈ [0, 1] across the cell); `l_nodes` (nx, ny, 4)
    the incremental inductances [H] at the nodes: ∂ψd/∂id, ∂ψd/∂iq, ∂ψq/∂id, ∂ψq/∂iq."""

    fmap: FluxMap
    coef_d: Array
    coef_q: Array
    l_nodes: Array

    def flux(self, i_d: float, i_q: float) -> tuple[float, float, Array]:
        """(ψd, ψq) [Wb] and the Jacobian [[∂ψd/∂id, ∂ψd/∂iq], [∂ψq/∂id, ∂ψq/∂iq]] [H] at currents [A] (the C
        kernel's fm_flux, in numpy: beyond the grid the first-order continuation from the nearest grid point)."""
        x, y = self.fmap.id_axis, self.fmap.iq_axis
        xc, yc = min(max(i_d, x[0]), x[-1]), min(max(i_q, y[0]), y[-1])
        ix = min(int(np.searchsorted(x, xc, side="right")) - 1, len(x) - 2)
        iy = min(int(np.searchsorted(y, yc, side="right")) - 1, len(y) - 2)
        hx, hy = x[ix + 1] - x[ix], y[iy + 1] - y[iy]
        u, v = (xc - x[ix]) / hx, (yc - y[iy]) / hy
        pu, pv = u ** np.arange(4), v ** np.arange(4)
        du = np.array([0.0, 1.0, 2.0 * u, 3.0 * u * u])
        dv = np.array([0.0, 1.0, 2.0 * v, 3.0 * v * v])
        out = []
        jac = np.zeros((2, 2))
        ddx, ddy = i_d - xc, i_q - yc
        for row, coef in enumerate((self.coef_d, self.coef_q)):
            a = coef[ix * (len(y) - 1) + iy].reshape(4, 4)
            f, fx, fy, fxy = pu @ a @ pv, du @ a @ pv / hx, pu @ a @ dv / hy, du @ a @ dv / (hx * hy)
            out.append(float(f + fx * ddx + fy * ddy))
            # the continuation's exact Jacobian (fluxmap.c fm_flux)
            jac[row] = (fx + (fxy * ddy if ddx == 0.0 else 0.0), fy + (fxy * ddx if ddy == 0.0 else 0.0))
        return out[0], out[1], jac

    def currents(self, psi_d: float, psi_q: float, guess: tuple[float, float] = (0.0, 0.0)) -> tuple[float, float]:
        """Currents [A] of a flux [Wb] by Newton's method on `flux` (InputFileError if it does not converge)."""
        i = np.array(guess, dtype=float)
        for _ in range(100):
            fd, fq, jac = self.flux(float(i[0]), float(i[1]))
            step = np.linalg.solve(jac, [psi_d - fd, psi_q - fq])
            i += step
            if np.abs(step).sum() <= 1e-13 * (1.0 + np.abs(i).sum()):
                return float(i[0]), float(i[1])
        raise InputFileError(f"flux map {self.fmap.source}: no current for ψ = ({psi_d}, {psi_q}) Wb")


def interpolant(fmap: FluxMap) -> Interpolant:
    """The bicubic Hermite interpolant of a map (see the module docstring)."""
    x, y = fmap.id_axis, fmap.iq_axis
    hx, hy = np.diff(x)[:, None], np.diff(y)[None, :]
    coefs = []
    slopes = []
    for f in (fmap.psi_d, fmap.psi_q):
        fx = pchip_slopes(x, f)
        fy = pchip_slopes(y, f.T).T
        fxy = pchip_slopes(y, fx.T).T
        slopes.append((fx, fy))
        corners = np.empty((len(x) - 1, len(y) - 1, 4, 4))
        for a, (dx, dy) in enumerate(((0, 0), (1, 0))):
            for b, (ex, ey) in enumerate(((0, 0), (0, 1))):
                sl = (slice(dx + ex, len(x) - 1 + dx + ex), slice(dy + ey, len(y) - 1 + dy + ey))
                corners[:, :, a, b] = f[sl]
                corners[:, :, a, 2 + b] = fy[sl] * hy
                corners[:, :, 2 + a, b] = fx[sl] * hx
                corners[:, :, 2 + a, 2 + b] = fxy[sl] * hx * hy
        coefs.append(np.einsum("ij,xyjk,lk->xyil", _M, corners, _M).reshape(-1, 16))
    (dd_x, dd_y), (dq_x, dq_y) = slopes
    return Interpolant(fmap, np.ascontiguousarray(coefs[0]), np.ascontiguousarray(coefs[1]),
                       np.stack([dd_x, dd_y, dq_x, dq_y], axis=-1))


@dataclass(frozen=True, slots=True)
class MapChecks:
    """What the load checks measured: reciprocity residual |∂ψd/∂iq − ∂ψq/∂id| at the nodes, max and RMS [H], and
    relative to the mean incremental self-inductance; the smallest secant ∂ψd/∂id and ∂ψq/∂iq [H] along the grid
    lines (> 0: monotone); the smallest node determinant of the incremental inductance matrix [H²]; the largest
    ‖L⁻¹‖∞ at the nodes [1/H]; the current range of the grid [A]; the flux at zero current [Wb]."""

    reciprocity_max_h: float
    reciprocity_rms_h: float
    reciprocity_rel: float
    min_secant_dd_h: float
    min_secant_qq_h: float
    min_det_h2: float
    inv_l_max: float
    id_range_a: tuple[float, float]
    iq_range_a: tuple[float, float]
    psi_at_zero_wb: tuple[float, float]

    def covers(self, i_trip: float) -> bool:
        """The grid reaches the trip current [A] in −id, +iq and −iq (the directions a PMSM drive takes: +id
        beyond the grid is the first-order continuation)."""
        return -self.id_range_a[0] >= i_trip and self.iq_range_a[1] >= i_trip and -self.iq_range_a[0] >= i_trip


def check_map(interp: Interpolant) -> MapChecks:
    """Checks of a map (InputFileError naming the file and the first failure: not monotone, singular)."""
    fmap = interp.fmap
    x, y = fmap.id_axis, fmap.iq_axis
    sec_d = np.diff(fmap.psi_d, axis=0) / np.diff(x)[:, None]
    sec_q = np.diff(fmap.psi_q, axis=1) / np.diff(y)[None, :]
    for name, sec, axis in (("psi_d", sec_d, "id"), ("psi_q", sec_q, "iq")):
        if not (sec > 0.0).all():
            k, m = np.unravel_index(int(np.argmin(sec)), sec.shape)
            raise InputFileError(f"flux map {fmap.source}: {name} is not increasing in {axis} near id = "
                                 f"{x[k]:g} A, iq = {y[m]:g} A (secant {sec[k, m]:.4g} H): the currents of a flux "
                                 "would not be unique")
    ln = interp.l_nodes
    det = ln[..., 0] * ln[..., 3] - ln[..., 1] * ln[..., 2]
    if not (det > 0.0).all():
        k, m = np.unravel_index(int(np.argmin(det)), det.shape)
        raise InputFileError(f"flux map {fmap.source}: incremental inductance matrix singular at id = {x[k]:g} A, "
                             f"iq = {y[m]:g} A (det {det[k, m]:.3g} H²)")
    inv = np.stack([ln[..., 3], -ln[..., 1], -ln[..., 2], ln[..., 0]], axis=-1) / det[..., None]
    inv_norm = np.maximum(np.abs(inv[..., 0]) + np.abs(inv[..., 1]), np.abs(inv[..., 2]) + np.abs(inv[..., 3]))
    resid = np.abs(ln[..., 1] - ln[..., 2])
    scale = float(np.mean(0.5 * (ln[..., 0] + ln[..., 3])))
    interp_zero = interp.flux(0.0, 0.0)
    return MapChecks(float(resid.max()), float(np.sqrt(np.mean(resid**2))), float(resid.max()) / scale,
                     float(sec_d.min()), float(sec_q.min()), float(det.min()), float(inv_norm.max()),
                     (float(x[0]), float(x[-1])), (float(y[0]), float(y[-1])), (interp_zero[0], interp_zero[1]))


def grid_from_points(i_d: Array, i_q: Array, psi_d: Array, psi_q: Array, source: str) -> FluxMap:
    """A FluxMap from scattered rows that form a full rectangular grid (each (id, iq) pair once); the iq ≥ 0 half
    of a map is completed by the d-axis symmetry. InputFileError naming the problem."""
    xs, ys = np.unique(i_d), np.unique(i_q)
    if len(xs) < 2 or len(ys) < 2:
        raise InputFileError(f"flux map {source}: the grid needs ≥ 2 values of id and of iq, got {len(xs)} × "
                             f"{len(ys)}")
    if len(i_d) != len(xs) * len(ys):
        raise InputFileError(f"flux map {source}: {len(i_d)} points do not form the rectangular grid of "
                             f"{len(xs)} id × {len(ys)} iq values (each pair exactly once)")
    kx, ky = np.searchsorted(xs, i_d), np.searchsorted(ys, i_q)
    seen = np.zeros((len(xs), len(ys)), dtype=bool)
    seen[kx, ky] = True
    if not seen.all():
        k, m = np.argwhere(~seen)[0]
        raise InputFileError(f"flux map {source}: grid point id = {xs[k]:g} A, iq = {ys[m]:g} A is missing "
                             "(a pair is given twice)")
    pd, pq = np.empty(seen.shape), np.empty(seen.shape)
    pd[kx, ky], pq[kx, ky] = psi_d, psi_q
    if ys[0] == 0.0:
        return FluxMap(xs, np.concatenate([-ys[:0:-1], ys]), np.concatenate([pd[:, :0:-1], pd], axis=1),
                       np.concatenate([-pq[:, :0:-1], pq], axis=1), source, mirrored=True)
    return FluxMap(xs, ys, pd, pq, source)


def read_csv_map(path: Path) -> FluxMap:
    """A map from a CSV with the header columns id, iq, psi_d, psi_q (A, Wb; other columns ignored)."""
    try:
        handle = path.open(newline="", encoding="utf-8")
    except OSError as exc:
        raise InputFileError(f"flux map {path}: {exc.strerror}") from None
    with handle:
        reader = csv.reader(handle)
        header = [h.strip() for h in next(reader, [])]
        missing = [c for c in CSV_COLUMNS if c not in header]
        if missing:
            raise InputFileError(f"flux map {path}: missing column(s) {', '.join(missing)} (header: "
                                 f"{','.join(header)}; need {','.join(CSV_COLUMNS)})")
        cols = [header.index(c) for c in CSV_COLUMNS]
        rows: list[list[float]] = []
        for row_no, row in enumerate(reader, start=2):
            if not row or all(not c.strip() for c in row):
                continue
            values = []
            for c, name in zip(cols, CSV_COLUMNS, strict=True):
                try:
                    v = float(row[c])
                except (ValueError, IndexError):
                    raise InputFileError(f"flux map {path}: line {row_no}, column '{name}': not a number") from None
                if not math.isfinite(v):
                    raise InputFileError(f"flux map {path}: line {row_no}, column '{name}': not finite")
                values.append(v)
            rows.append(values)
    if not rows:
        raise InputFileError(f"flux map {path}: no data rows")
    data = np.array(rows)
    return grid_from_points(data[:, 0], data[:, 1], data[:, 2], data[:, 3], str(path))


def read_flux_map(path: Path) -> FluxMap:
    """A map file by its suffix: `.csv` or a SyR-e `.mat`."""
    if path.suffix.lower() == ".mat":
        from pmsm_hil.hil.fluxmap_syre import read_syre_mat

        return read_syre_mat(path)
    if path.suffix.lower() != ".csv":
        raise InputFileError(f"flux map {path}: unknown format (a .csv with id,iq,psi_d,psi_q, or a SyR-e .mat)")
    return read_csv_map(path)


@lru_cache(maxsize=16)
def _load(path: str, mtime_ns: int, size: int) -> tuple[Interpolant, MapChecks]:
    interp = interpolant(read_flux_map(Path(path)))
    return interp, check_map(interp)


def load_interpolant(path: str) -> tuple[Interpolant, MapChecks]:
    """The interpolant and checks of a map file, cached while the file is unchanged."""
    p = Path(path)
    try:
        st = p.stat()
    except OSError as exc:
        raise InputFileError(f"flux map {path}: {exc.strerror}") from None
    return _load(str(p.resolve()), st.st_mtime_ns, st.st_size)


def write_csv_map(fmap: FluxMap, path: Path) -> None:
    """Write a map as CSV rows id, iq, psi_d, psi_q (id slowest)."""
    with path.open("w", newline="", encoding="utf-8") as out:
        w = csv.writer(out)
        w.writerow(CSV_COLUMNS)
        for k, i_d in enumerate(fmap.id_axis):
            for m, i_q in enumerate(fmap.iq_axis):
                w.writerow([repr(float(i_d)), repr(float(i_q)), repr(float(fmap.psi_d[k, m])),
                            repr(float(fmap.psi_q[k, m]))])


__all__ = ["CSV_COLUMNS", "FluxMap", "Interpolant", "MapChecks", "check_map", "grid_from_points", "interpolant",
           "load_interpolant", "pchip_slopes", "read_csv_map", "read_flux_map", "write_csv_map"]
