"""Dead time of the induction machine kernel (as the three-phase PMSM kernel's): a phase without current at its
gate edge is open for the dead time — checked against an independent αβ formulation of the open phase (i_a held at
zero by its floating voltage, scipy.linalg.expm) — and a diode current that reaches zero inside the dead time
blocks: the phase is open from there (i_a = 0 exactly, i_b = −i_c) until the dead time ends."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from scipy.linalg import expm

from pmsm_hil.hil.im_params import ImParams
from pmsm_hil.hil.im_plant import ImPlant
from pmsm_hil.hil.mechanics import DynoMechanics
from pmsm_hil.hil.presets_loader import load_motor

TS_S = 1e-4
RPM = 1000.0


def _params(t_dead: float) -> ImParams:
    p = load_motor("im-2k2", {"t_dead": t_dead})
    assert isinstance(p, ImParams)
    return p


def _closed(p: ImParams, omega_e: float, u: tuple[float, float]) -> npt.NDArray[np.float64]:
    """dx/dt = F x, x = (ψsα, ψsβ, ψRα, ψRβ, 1), all phases connected, stator voltage u [V]."""
    a, r_r, r_m = p.rs / p.lsigma, p.rr / p.lsigma, p.rr / p.lm
    f = np.zeros((5, 5))
    f[0:2, 0:2], f[0:2, 2:4], f[0:2, 4] = -a * np.eye(2), a * np.eye(2), u
    f[2:4, 0:2] = r_r * np.eye(2)
    f[2:4, 2:4] = -(r_r + r_m) * np.eye(2) + omega_e * np.array([[0.0, -1.0], [1.0, 0.0]])
    return f


def _phase_a_open(p: ImParams, omega_e: float, u_beta: float) -> npt.NDArray[np.float64]:
    """Phase a open (i_sα = i_a = 0): the floating phase voltage keeps dψsα/dt = dψRα/dt; β as connected."""
    r_m = p.rr / p.lm
    f = np.zeros((5, 5))
    i_beta = np.array([0.0, 1.0, 0.0, -1.0, 0.0]) / p.lsigma
    d_psi_ra = np.array([0.0, 0.0, -r_m, -omega_e, 0.0])  # RR·i_sα (= 0) − (RR/LM)·ψRα − ωe·ψRβ
    f[2] = d_psi_ra
    f[0] = d_psi_ra
    f[3] = p.rr * i_beta + np.array([0.0, 0.0, omega_e, -r_m, 0.0])
    f[1] = -p.rs * i_beta
    f[1, 4] = u_beta
    return f


def _voltage(vdc: float, code: int) -> tuple[float, float]:
    sa, sb, sc = (code >> 2) & 1, (code >> 1) & 1, code & 1
    return vdc * (2 * sa - sb - sc) / 3.0, vdc / math.sqrt(3.0) * (sb - sc)


def test_a_phase_without_current_is_open_for_the_dead_time() -> None:
    t_dead = 3e-6
    p = _params(t_dead)
    omega_e = p.pole_pairs * RPM * 2.0 * math.pi / 60.0
    plant = ImPlant(p, TS_S, DynoMechanics(RPM), trace_dt_s=None)
    # magnetized, i_a = i_sα = 0 exactly, i_sβ = 3 A; code 3 (b, c high: the c leg's edge below is the only one)
    psi_r = np.array([0.6, 0.5])
    psi_s = psi_r + p.lsigma * np.array([0.0, 3.0])
    plant.set_state(psi_s=(psi_s[0], psi_s[1]), psi_r=(psi_r[0], psi_r[1]), gate=0)
    # gate 0 -> 4: leg a rises with no current (open for t_dead), legs b, c stay low (v_bc = 0)
    stats = plant.advance([4], [100_000])
    assert stats.open_phase_events == 0  # open from the edge, not by blocking
    x = np.array([*psi_s, *psi_r, 1.0])
    x = expm(_phase_a_open(p, omega_e, 0.0) * t_dead) @ x
    assert abs((x[0] - x[2]) / p.lsigma) < 1e-12  # i_a stayed zero in the reference
    x = expm(_closed(p, omega_e, _voltage(p.vdc, 4)) * (TS_S - t_dead)) @ x
    want = (x[0:2] - x[2:4]) / p.lsigma
    smp = plant.sample()
    got = np.array([smp.i_a, (smp.i_b - smp.i_c) / math.sqrt(3.0)])
    print(f"open phase for {t_dead * 1e6:g} µs, then closed: |Δi| = {np.abs(got - want).max():.2e} A")
    assert np.abs(got - want).max() < 1e-9
    assert np.allclose(plant.psi_r, x[2:4], rtol=0, atol=1e-11)


def test_a_diode_current_reaching_zero_opens_the_phase() -> None:
    t_dead = 3e-6
    p = _params(t_dead)
    plant = ImPlant(p, TS_S, DynoMechanics(RPM), trace_dt_s=1e-7)
    # i_a = +0.01 A (out of the leg), i_b = 2 A, i_c = -2.01 A; gate 2 (b high) -> 6 (a, b high): leg a's lower
    # diode conducts (v_a < 0) and its current falls through zero within ~1.2 µs of the 3 µs dead time
    i_al, i_be = 0.01, (2.0 - (-2.01)) / math.sqrt(3.0)
    psi_r = (0.8, 0.1)
    plant.set_state(psi_s=(psi_r[0] + p.lsigma * i_al, psi_r[1] + p.lsigma * i_be), psi_r=psi_r, gate=2)
    stats = plant.advance([6], [100_000])
    assert stats.open_phase_events == 1
    tr = plant.last_trace
    t, i_a, i_b, i_c = tr[:, 0], tr[:, 1], tr[:, 2], tr[:, 3]
    window = (t > 1.5e-6) & (t < t_dead - 1e-9)
    assert window.sum() >= 10
    assert (i_a[window] == 0.0).all()
    assert np.allclose(i_b[window], -i_c[window], rtol=0, atol=1e-12)
    assert i_a[1] < 0.01 and (i_a[(t > t_dead + 1e-7)] > 0.0).all()  # after the dead time the upper switch drives it up
