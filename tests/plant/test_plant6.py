"""Dual three-phase plant: VSD transform, voltage groups, accuracy against scipy, dead time, API."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest
from pmsm_hil.hil._plant_native import ffi, lib

from pmsm_hil.hil.errors import ParameterError, SequenceError
from pmsm_hil.hil.mechanics import DynoMechanics, InertiaMechanics, LoadProfile
from pmsm_hil.hil.plant6 import TRACE_COLUMNS6, Plant6
from pmsm_hil.hil.presets_loader import load_motor
from tests.plant.reference_solver import rows_and_references
from tests.plant.reference_solver6 import VSD, VSD_ROWS, code_voltage, solve_period6

TS = 100e-6
TS_NS = 100_000
MOTOR = "zhang2021-dtpmsm"


def _plant(rpm: float = 1500.0, **overrides: float) -> Plant6:
    return Plant6(load_motor(MOTOR, overrides), TS, DynoMechanics(rpm), trace_dt_s=None)


def test_vsd_round_trip_and_phase_angles() -> None:
    rng = np.random.default_rng(1)
    i6 = rng.normal(size=(6, 50))
    assert np.allclose(VSD_ROWS.T @ (VSD @ i6), i6, atol=1e-12)  # T^-1 = 3 T^T
    angles = np.radians([0, 120, 240, 30, 150, 270])
    assert np.allclose(VSD_ROWS[0], np.cos(angles)) and np.allclose(VSD_ROWS[1], np.sin(angles))
    assert np.allclose(VSD_ROWS[2], np.cos(5 * angles)) and np.allclose(VSD_ROWS[3], np.sin(5 * angles))


def test_kernel_phase_currents_are_the_inverse_vsd() -> None:
    out = ffi.new("double[6]")
    rng = np.random.default_rng(2)
    for _ in range(20):
        i_d, i_q, th, i_x, i_y = rng.normal(size=5) * [10, 10, 3, 5, 5]
        lib.p6_phase_currents(i_d, i_q, th, i_x, i_y, out)
        phases = np.array(list(out))
        back = VSD @ phases
        i_al, i_be = i_d * math.cos(th) - i_q * math.sin(th), i_d * math.sin(th) + i_q * math.cos(th)
        assert np.allclose(back, [i_al, i_be, i_x, i_y, 0.0, 0.0], atol=1e-12)


def test_64_states_group_amplitudes() -> None:
    v = ffi.new("double[4]")
    mags = []
    for code in range(64):
        lib.p6_code_voltage(1.0, code, v)
        assert np.allclose(list(v), code_voltage(code, 1.0), atol=1e-12)
        mags.append(round(math.hypot(v[0], v[1]), 3))
    counts = {m: mags.count(m) for m in set(mags)}
    assert counts == {0.0: 4, 0.173: 12, 0.333: 24, 0.471: 12, 0.644: 12}
    assert [c for c in range(64) if mags[c] == 0.0] == [0, 7, 56, 63]


def test_accuracy_against_scipy_within_1ma() -> None:
    params = load_motor(MOTOR)
    rng = np.random.default_rng(11)
    worst = 0.0
    omega = 1500 * 2 * math.pi / 60
    plant = Plant6(params, TS, DynoMechanics(1500.0), theta0_rad=0.4, trace_dt_s=None)
    for _ in range(300):
        cuts = np.sort(rng.integers(0, TS_NS + 1, 2))
        durs = [int(cuts[0]), int(cuts[1] - cuts[0]), int(TS_NS - cuts[1])]
        states = [int(s) for s in rng.integers(0, 64, 3)]
        s0 = plant.sample()
        x, _ = solve_period6(params, omega, s0.theta_e, (s0.i_d, s0.i_q, s0.i_x, s0.i_y), states,
                             [d * 1e-9 for d in durs])
        plant.advance(states, durs)
        s1 = plant.sample()
        worst = max(worst, float(np.max(np.abs(np.array([s1.i_d, s1.i_q, s1.i_x, s1.i_y]) - x))))
        if abs(s1.i_d) > 200 or abs(s1.i_x) > 200:  # keep the random walk in a sane range
            plant.set_state(i_d=0.0, i_q=0.0, i_x=0.0, i_y=0.0)
    assert worst <= 1e-3, f"max |Δi| = {worst:.3e} A"


def test_torque_has_pole_pair_factor_three() -> None:
    plant = _plant()
    plant.set_state(i_q=10.0)
    p = plant.params
    assert plant.sample().torque == pytest.approx(3 * p.pole_pairs * p.psi_f * 10.0)  # 12 N·m, not 3 or 6


def test_xy_current_settles_to_v_over_r_and_dq_unaffected() -> None:
    """A G1 vector for ~5 L_ls/R... only in x-y: check the exact exponential against the closed form."""
    params = load_motor(MOTOR)
    plant = Plant6(params, TS, DynoMechanics(0.0), trace_dt_s=TS / 10)
    plant.advance([9], [TS_NS])
    vx, vy = code_voltage(9, params.vdc)[2:]
    k = 1 - math.exp(-params.rs * TS / params.lls)
    smp = plant.sample()
    assert smp.i_x == pytest.approx(vx / params.rs * k, rel=1e-9)
    assert smp.i_y == pytest.approx(vy / params.rs * k, rel=1e-9)
    tr = plant.last_trace
    assert tr.shape == (10, len(TRACE_COLUMNS6))
    # trace columns i_x, i_y follow the same exponential
    tau = tr[:, 0]
    assert np.allclose(tr[:, 9], vx / params.rs * (1 - np.exp(-params.rs * tau / params.lls)), atol=1e-9)


def test_zero_sum_per_set_and_sample_fields() -> None:
    plant = _plant()
    for code in (9, 27, 45, 10):
        plant.advance([code], [TS_NS])
    s = plant.sample()
    assert s.i_a + s.i_b + s.i_c == pytest.approx(0.0, abs=1e-9)
    assert s.i_u + s.i_v + s.i_w == pytest.approx(0.0, abs=1e-9)
    assert s.vdc == 300.0 and len(s.phase_currents) == 6


def test_dead_time_sign_rule_per_leg() -> None:
    """Leg A carries positive current: during dead time its lower diode holds it low, so a 0→1 edge
    acts t_dead late — equal to an ideal plant with the pulse shortened by t_dead."""
    t_dead = 2e-6
    dead = _plant(0.0, t_dead=t_dead)
    ideal = _plant(0.0)
    for p in (dead, ideal):
        p.set_state(i_d=20.0)  # θ = 0: i_A = i_alpha + i_x = 20 A > 0
    dead.advance([0, 32, 0], [40_000, 20_000, 40_000])
    ideal.advance([0, 32, 0], [42_000, 18_000, 40_000])
    a, b = dead.sample(), ideal.sample()
    assert a.i_d == pytest.approx(b.i_d, abs=1e-9) and a.i_x == pytest.approx(b.i_x, abs=1e-9)


def test_inertia_mode_accelerates_with_torque() -> None:
    params = load_motor(MOTOR)
    plant = Plant6(params, TS, InertiaMechanics(LoadProfile.constant(0.0), initial_speed_rpm=0.0),
                   trace_dt_s=None)
    plant.set_state(i_q=50.0)
    plant.advance([0], [TS_NS])  # i_q barely decays (L/R = 0.2 s): T ≈ 60 N·m over 100 µs
    assert plant.sample().omega_m == pytest.approx(60.0 * TS / params.j, rel=2e-3)


def test_bad_input_errors() -> None:
    with pytest.raises(ParameterError, match="lls"):
        Plant6(load_motor("niu2020-ipmsm"), TS, DynoMechanics(0.0))
    plant = _plant()
    with pytest.raises(SequenceError, match=r"0\.\.63"):
        plant.advance([64], [TS_NS])
    with pytest.raises(SequenceError, match="sum"):
        plant.advance([1], [TS_NS - 1])
    with pytest.raises(SequenceError, match="gate"):
        plant.set_state(gate=99)


def test_lls_parameter_override_and_default() -> None:
    assert load_motor("niu2020-ipmsm").lls == 0.0
    assert not load_motor("niu2020-ipmsm").is_six_phase
    assert load_motor(MOTOR, {"lls": 1e-4}).lls == 1e-4
    with pytest.raises(ParameterError, match="lls"):
        load_motor(MOTOR, {"lls": -1.0})


def test_trace_rows_equal_the_closed_form_at_their_times() -> None:
    """Six-phase trace rows (stepped by addition theorems, x-y decay by its step factor) equal the state a second
    plant reaches when its period ends exactly at the row's time."""
    params = load_motor(MOTOR)
    ts_ns, dt_ns, code = round(TS * 1e9), 700, 0b100011
    traced = Plant6(params, TS, DynoMechanics(1000.0), trace_dt_s=dt_ns * 1e-9)
    for st in (0b110001, 0b010011, code, code):
        traced.advance([st], [ts_ns])
    start = traced.sample()
    traced.advance([code], [ts_ns])  # same vector as before: no gate edge inside the period
    rows = traced.last_trace.copy()

    def reference(offset_ns: int) -> Any:
        ref_plant = Plant6(params, offset_ns * 1e-9, DynoMechanics(1000.0), trace_dt_s=None)
        ref_plant.set_state(i_d=start.i_d, i_q=start.i_q, i_x=start.i_x, i_y=start.i_y, theta_e=start.theta_e,
                            gate=code)
        ref_plant.advance([code], [offset_ns])
        return ref_plant.sample()

    checked, worst = 0, 0.0
    for row, ref in rows_and_references(rows, start.t, reference):
        worst = max(worst, *(abs(row[1 + k] - ref.phase_currents[k]) for k in range(6)),
                    abs(row[9] - ref.i_x), abs(row[10] - ref.i_y))
        assert row[7] == pytest.approx(ref.torque, rel=1e-11)
        checked += 1
    scale = float(np.abs(rows[:, 1:7]).max())
    assert checked >= rows.shape[0] - 2
    assert worst < 1e-12 * scale  # rounding only
