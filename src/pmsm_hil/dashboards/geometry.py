"""Inverter voltage-vector geometry for the αβ (and x-y) planes of the dashboard.

Three phases: u_αβ = 2/3·Vdc·(Sa + a·Sb + a²·Sc), a = exp(j·2π/3), switching code 4·Sa + 2·Sb + Sc
(docs/architecture.md); the active vectors span a hexagon of circumradius 2/3·Vdc [V].
Six phases (asymmetric, sets ABC and UVW shifted by 30°), 6-bit code [S_A S_B S_C S_U S_V S_W] with S_A
the most significant: vector space decomposition with phase angles θ_k = 0°, 120°, 240°, 30°, 150°, 270°;
αβ = 1/3·Vdc·Σ S_k·exp(j·θ_k), x-y = 1/3·Vdc·Σ S_k·exp(j·5·θ_k).
"""

from __future__ import annotations

from typing import Final

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

#: MPCC vector index (vector_id 0..7) → switching code (docs/algorithms/mpcc.md).
VECTOR_STATE: Final = (0, 4, 6, 2, 3, 1, 5, 7)
#: The seven distinct candidate vectors of a two-level three-phase inverter (one zero code).
CANDIDATE_CODES_3PH: Final = (0, 4, 6, 2, 3, 1, 5)

_THETA_3: Final = np.array([0.0, 2.0 * np.pi / 3.0, 4.0 * np.pi / 3.0])
_THETA_6: Final = np.deg2rad(np.array([0.0, 120.0, 240.0, 30.0, 150.0, 270.0]))


def _bits(codes: npt.ArrayLike, legs: int) -> FloatArray:
    c = np.asarray(codes, dtype=np.int64)
    shifts = np.arange(legs - 1, -1, -1)
    out: FloatArray = ((c[..., None] >> shifts) & 1).astype(np.float64)
    return out


def state_voltage_ab(codes: npt.ArrayLike, vdc: float) -> FloatArray:
    """αβ voltage [V] of three-phase switching codes (0..7); shape (..., 2)."""
    s = _bits(codes, 3)
    k = 2.0 / 3.0 * vdc
    out: FloatArray = np.stack([k * (s @ np.cos(_THETA_3)), k * (s @ np.sin(_THETA_3))], axis=-1)
    return out


def mean_voltage_ab(states: npt.ArrayLike, durations_ns: npt.ArrayLike, n_states: npt.ArrayLike,
                    vdc: float) -> FloatArray:
    """Duration-weighted mean αβ voltage [V] of each period's sequence; states/durations shape (n, 3)."""
    st = np.asarray(states)
    dur = np.asarray(durations_ns, dtype=np.float64).copy()
    valid = np.arange(st.shape[1])[None, :] < np.asarray(n_states)[:, None]
    dur[~valid] = 0.0
    total = dur.sum(axis=1)
    total[total == 0.0] = 1.0
    v = state_voltage_ab(st, vdc)  # (n, 3, 2)
    out: FloatArray = (v * dur[..., None]).sum(axis=1) / total[:, None]
    return out


def duty_voltage_ab(duties: npt.ArrayLike, vdc: float) -> FloatArray:
    """Mean αβ voltage [V] of each period's duty cycles of legs a, b, c (shape (n, ≥3)): the leg voltages d·Vdc
    through the amplitude-invariant Clarke transform (the common mode drops out)."""
    d = np.asarray(duties, dtype=np.float64)[:, :3] * vdc
    out: FloatArray = np.stack([(2.0 * d[:, 0] - d[:, 1] - d[:, 2]) / 3.0, (d[:, 1] - d[:, 2]) / np.sqrt(3.0)],
                               axis=-1)
    return out


def hexagon(vdc: float) -> FloatArray:
    """Closed outline of the three-phase vector hexagon [V]: 7 points, V1..V6 and back to V1."""
    pts = state_voltage_ab(np.array([4, 6, 2, 3, 1, 5, 4]), vdc)
    return pts


def linear_limit_circle(vdc: float, points: int = 73) -> FloatArray:
    """Inscribed circle of the hexagon (radius Vdc/√3 [V]): the linear-modulation limit."""
    a = np.linspace(0.0, 2.0 * np.pi, points)
    r = vdc / np.sqrt(3.0)
    out: FloatArray = np.stack([r * np.cos(a), r * np.sin(a)], axis=-1)
    return out


def six_phase_vsd(codes: npt.ArrayLike, vdc: float) -> tuple[FloatArray, FloatArray]:
    """(αβ, x-y) voltages [V] of six-phase 6-bit switching codes; each shape (..., 2)."""
    s = _bits(codes, 6)
    k = vdc / 3.0
    ab: FloatArray = np.stack([k * (s @ np.cos(_THETA_6)), k * (s @ np.sin(_THETA_6))], axis=-1)
    xy: FloatArray = np.stack([k * (s @ np.cos(5.0 * _THETA_6)), k * (s @ np.sin(5.0 * _THETA_6))], axis=-1)
    return ab, xy
