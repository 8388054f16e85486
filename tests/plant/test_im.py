"""The induction machine kind "im" (preset im-2k2): `hil plant replay` from zero flux against an independent
matrix-exponential solution (scipy.linalg.expm of the real 4-state inverse-Γ model, not the kernel's complex
closed form), the kind's registration, its preset and its parameter errors."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pytest
from scipy.linalg import expm

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.im_params import ImParams
from pmsm_hil.hil.im_plant import ImPlant
from pmsm_hil.hil.machine import load_machine
from pmsm_hil.hil.mechanics import DynoMechanics, InertiaMechanics, LoadProfile
from pmsm_hil.hil.presets_loader import load_motor

TS_S = 1e-4
RPM = 1000.0
PERIODS = 2000


def _reference_matrix(p: ImParams, omega_e: float) -> npt.NDArray[np.float64]:
    """Augmented 7x7 system of x = (ψsα, ψsβ, ψRα, ψRβ, uα, uβ, 1): dx/dt = F x, the voltage constant."""
    a, r_r, r_m = p.rs / p.lsigma, p.rr / p.lsigma, p.rr / p.lm
    f = np.zeros((7, 7))
    f[0:2, 0:2] = -a * np.eye(2)
    f[0:2, 2:4] = a * np.eye(2)
    f[0:2, 4:6] = np.eye(2)
    f[2:4, 0:2] = r_r * np.eye(2)
    f[2:4, 2:4] = -(r_r + r_m) * np.eye(2) + omega_e * np.array([[0.0, -1.0], [1.0, 0.0]])
    return f


def _code_voltage(vdc: float, code: int) -> tuple[float, float]:
    sa, sb, sc = (code >> 2) & 1, (code >> 1) & 1, code & 1
    return vdc * (2 * sa - sb - sc) / 3.0, vdc / math.sqrt(3.0) * (sb - sc)


def _random_sequence(rng: np.random.Generator) -> list[tuple[list[int], list[int]]]:
    """PERIODS periods of three random codes with random ns durations summing to Ts."""
    ts_ns = round(TS_S * 1e9)
    out = []
    for _ in range(PERIODS):
        cuts = np.sort(rng.integers(0, ts_ns + 1, size=2))
        durs = [int(cuts[0]), int(cuts[1] - cuts[0]), int(ts_ns - cuts[1])]
        out.append(([int(c) for c in rng.integers(0, 8, size=3)], durs))
    return out


def test_replay_from_zero_flux_matches_an_independent_matrix_exponential(tmp_path: Path) -> None:
    seq = _random_sequence(np.random.default_rng(28))
    src, dst = tmp_path / "in.csv", tmp_path / "out.csv"
    with src.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle)
        writer.writerow(["s0", "t0", "s1", "t1", "s2", "t2"])
        for codes, durs in seq:
            writer.writerow([v for c, d in zip(codes, durs, strict=True) for v in (c, f"{d}e-9")])
    rc = main(["plant", "replay", "--motor", "im-2k2", "--rpm", str(RPM), "--ts", str(TS_S), "--input", str(src),
               "--output", str(dst)])
    assert rc == 0
    with dst.open(newline="", encoding="utf-8") as handle:
        rows = list(csv.reader(handle))
    head = rows[0]
    got = np.array([[float(v) for v in row] for row in rows[1:]])
    assert got.shape == (PERIODS + 1, len(head))

    p = load_motor("im-2k2")
    assert isinstance(p, ImParams)
    omega_e = p.pole_pairs * RPM * 2.0 * math.pi / 60.0
    f = _reference_matrix(p, omega_e)
    x = np.zeros(7)
    x[6] = 1.0
    currents = [np.zeros(2)]
    torques = [0.0]
    step_cache: dict[int, npt.NDArray[np.float64]] = {}
    for codes, durs in seq:
        for code, dur in zip(codes, durs, strict=True):
            x[4:6] = _code_voltage(p.vdc, code)
            if dur not in step_cache:
                step_cache[dur] = expm(f * (dur * 1e-9))
            x = step_cache[dur] @ x
        i_s = (x[0:2] - x[2:4]) / p.lsigma
        currents.append(i_s)
        torques.append(1.5 * p.pole_pairs * (x[0] * i_s[1] - x[1] * i_s[0]))
    ref = np.array(currents)
    ia = ref[:, 0]
    ib = -0.5 * ref[:, 0] + 0.5 * math.sqrt(3.0) * ref[:, 1]
    ic = -0.5 * ref[:, 0] - 0.5 * math.sqrt(3.0) * ref[:, 1]
    err = max(np.abs(got[:, head.index(name)] - want).max() for name, want in (("i_a", ia), ("i_b", ib), ("i_c", ic)))
    print(f"im-2k2 replay, {PERIODS} periods at {RPM:.0f} rpm from zero flux: max |Δi| = {err:.3e} A, "
          f"peak |i| = {np.abs(ia).max():.2f} A")
    assert np.abs(ia).max() > 1.0  # the sequence drove real currents
    assert err <= 1e-6
    assert np.abs(got[:, head.index("torque")] - np.array(torques)).max() <= 1e-5
    theta = got[:, head.index("theta_e")]
    want_theta = np.mod(omega_e * TS_S * np.arange(PERIODS + 1), 2.0 * math.pi)
    assert np.abs(np.angle(np.exp(1j * (theta - want_theta)))).max() < 1e-9


def test_im_2k2_is_the_im_kind_with_motulators_parameters() -> None:
    m = load_machine("im-2k2")
    assert m.layout.kind == "im" and m.phases == 3 and m.layout.native_kernel == "im_kernel"
    p = m.params
    assert isinstance(p, ImParams)
    assert (p.rs, p.rr, p.lsigma, p.lm, p.pole_pairs, p.j) == (3.7, 2.1, 0.021, 0.224, 2, 0.015)
    assert p.torque_rating_nm == 14.6 and p.vdc == 540.0


def test_steady_state_torque_matches_the_equivalent_circuit() -> None:
    """Held speed, a sinusoidal-average drive replaced by the exact steady state: start the plant on the
    steady-state fluxes of a voltage phasor and check the torque formula 1.5·n_p·Im{i_s conj(ψs)} against the
    slip formula T = 1.5·n_p·|ψR|²·ω_r/RR."""
    p = load_motor("im-2k2")
    assert isinstance(p, ImParams)
    plant = ImPlant(p, TS_S, DynoMechanics(1000.0), trace_dt_s=None)
    psi_r = 0.9
    omega_slip = 12.0  # [rad/s] electrical
    i_d = psi_r / p.lm
    i_q = omega_slip * psi_r / p.rr
    plant.set_state(psi_r=(psi_r, 0.0), psi_s=(psi_r + p.lsigma * i_d, p.lsigma * i_q))
    smp = plant.sample()
    assert smp.i_d == pytest.approx(i_d, abs=1e-12) and smp.i_q == pytest.approx(i_q, abs=1e-12)
    assert smp.torque == pytest.approx(1.5 * p.pole_pairs * psi_r**2 * omega_slip / p.rr, rel=1e-12)


def test_inertia_mode_accelerates_on_the_torque() -> None:
    p = load_motor("im-2k2")
    plant = ImPlant(p, TS_S, InertiaMechanics(LoadProfile.constant(0.0), 0.0), trace_dt_s=None)
    assert isinstance(p, ImParams)
    plant.set_state(psi_r=(0.9, 0.0), psi_s=(0.9 + p.lsigma * 4.0, p.lsigma * 5.0))
    t0 = plant.sample().torque
    plant.advance([0], [100_000])
    assert t0 > 0 and plant.sample().omega_m > 0


@pytest.mark.parametrize(("values", "needle"), [
    ({"rs": 3.7}, "missing induction-machine parameter"),
    ({"rs": 3.7, "rr": 2.1, "lsigma": 0.021, "lm": -1.0, "pole_pairs": 2, "vdc": 540, "j": 0.015}, "'lm'"),
    ({"rs": 3.7, "rr": 2.1, "lsigma": 0.021, "lm": 0.2, "pole_pairs": 2.5, "vdc": 540, "j": 0.015}, "pole_pairs"),
    ({"rs": 3.7, "rr": 2.1, "lsigma": 0.021, "lm": 0.2, "pole_pairs": 2, "vdc": 540, "j": 0.015, "ld": 1},
     "unknown induction-machine parameter(s) ld"),
])
def test_bad_parameters_name_the_key(values: dict[str, float], needle: str) -> None:
    with pytest.raises(ParameterError, match=needle.replace("(", r"\(").replace(")", r"\)")):
        ImParams.from_values(values, "x")


def test_set_override_and_unknown_name() -> None:
    p = load_motor("im-2k2", {"rr": 2.5})
    assert isinstance(p, ImParams) and p.rr == 2.5
    with pytest.raises(ParameterError, match="psi_f"):
        load_motor("im-2k2", {"psi_f": 0.1})
