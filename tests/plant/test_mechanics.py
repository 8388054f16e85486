"""Mechanical side: load profiles, dyno mode, inertia-mode physics (J·dω/dt = Te − T_load − B·ω)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.mechanics import RPM_TO_RAD_S, DynoMechanics, InertiaMechanics, LoadProfile
from pmsm_hil.hil.plant import Plant
from pmsm_hil.hil.presets_loader import load_motor
from tests.plant.reference_solver import stator_voltage

TS = 100e-6
TS_NS = 100_000


def test_constant_profile() -> None:
    prof = LoadProfile.constant(2.5)
    for t in (0.0, 1e-3, 10.0):
        assert prof.value_and_slope(t) == (2.5, 0.0)


def test_default_profile_is_zero_load() -> None:
    assert LoadProfile().value_and_slope(3.0) == (0.0, 0.0)


def test_steps_are_right_continuous_and_flat() -> None:
    prof = LoadProfile.steps(1.0, [(0.01, 3.0), (0.02, -2.0)])
    assert prof.value_and_slope(0.0) == (1.0, 0.0)
    assert prof.value_and_slope(0.009999) == (1.0, 0.0)
    assert prof.value_and_slope(0.01) == (3.0, 0.0)
    assert prof.value_and_slope(0.015) == (3.0, 0.0)
    assert prof.value_and_slope(0.02) == (-2.0, 0.0)
    assert prof.value_and_slope(5.0) == (-2.0, 0.0)


def test_ramp_interpolates_with_slope_and_holds_after_last_point() -> None:
    prof = LoadProfile(((0.0, 0.0), (0.01, 0.0), (0.03, 4.0)))
    assert prof.value_and_slope(0.005) == (0.0, 0.0)
    value, slope = prof.value_and_slope(0.02)
    assert value == pytest.approx(2.0) and slope == pytest.approx(200.0)
    assert prof.value_and_slope(0.03) == (4.0, 0.0)
    assert prof.value_and_slope(1.0) == (4.0, 0.0)


def test_before_first_point_holds_the_first_value() -> None:
    prof = LoadProfile(((0.5, 1.5), (1.0, 2.5)))
    assert prof.value_and_slope(0.1) == (1.5, 0.0)


@pytest.mark.parametrize(
    ("points", "fragment"),
    [((), "at least one"), (((0.0, math.nan),), "point 0"), (((math.inf, 1.0),), "point 0"),
     (((0.0, 1.0), (1.0, 2.0), (0.5, 3.0)), "point 2")],
)
def test_bad_profiles_name_the_point(points: tuple[tuple[float, float], ...], fragment: str) -> None:
    with pytest.raises(ParameterError, match=fragment):
        LoadProfile(points)


def test_dyno_speed_conversion() -> None:
    assert DynoMechanics(1500.0).omega_m == pytest.approx(1500.0 * 2 * math.pi / 60)
    assert pytest.approx(math.pi / 30) == RPM_TO_RAD_S


def test_dyno_mode_holds_speed_whatever_the_torque() -> None:
    plant = Plant(load_motor("niu2020-ipmsm"), TS, DynoMechanics(1000.0), trace_dt_s=None)
    for _ in range(50):
        plant.advance([4], [TS_NS])
    smp = plant.sample()
    assert abs(smp.torque) > 0.1
    assert smp.omega_m == 1000.0 * RPM_TO_RAD_S


def test_zero_vector_brakes_consistently_with_the_torque_integral() -> None:
    """Short-circuit braking from 1500 rpm: J·Δω equals ∫(Te − B·ω)dt of the 2 µs trace within 1 %."""
    params = load_motor("niu2020-ipmsm", {"b": 2e-3})
    plant = Plant(params, TS, InertiaMechanics(LoadProfile.constant(0.0), 1500.0), trace_dt_s=2e-6)
    w0 = plant.sample().omega_m
    rows = []
    for _ in range(300):
        plant.advance([0], [TS_NS])
        rows.append(plant.last_trace.copy())
    end = plant.sample()
    trace = np.vstack(rows)
    t = np.append(trace[:, 0], end.t)
    torque = np.append(trace[:, 4], end.torque)
    omega = np.append(trace[:, 5], end.omega_m)
    assert end.omega_m < 0.2 * w0  # it really braked
    assert np.all(torque[1:] < 0.0)  # braking torque throughout
    lhs = params.j * (end.omega_m - w0)
    rhs = float(np.trapezoid(torque - params.b * omega, t))
    assert lhs == pytest.approx(rhs, rel=1e-2)


def _no_flux_plant(load: LoadProfile, rpm: float, b: float = 0.0) -> Plant:
    # ψf = 0, zero vector, zero initial current: the current stays exactly zero, so Te = 0
    return Plant(load_motor("niu2020-ipmsm", {"psi_f": 0.0, "b": b}), TS, InertiaMechanics(load, rpm),
                 trace_dt_s=None)


def test_constant_load_with_zero_current_decelerates_at_load_over_j() -> None:
    plant = _no_flux_plant(LoadProfile.constant(0.65), 1000.0)
    w0 = plant.sample().omega_m
    j = plant.params.j
    for k in range(1, 201):
        plant.advance([0], [TS_NS])
        smp = plant.sample()
        assert smp.i_d == 0.0 and smp.i_q == 0.0 and smp.torque == 0.0
        assert smp.omega_m == pytest.approx(w0 - 0.65 / j * k * TS, rel=1e-12, abs=1e-9)


def test_ramp_and_step_loads_aligned_to_periods_are_integrated_exactly() -> None:
    # ramp 0 → 2 N·m over [1 ms, 3 ms], then a step to −1 N·m at 5 ms
    prof = LoadProfile(((0.0, 0.0), (1e-3, 0.0), (3e-3, 2.0), (5e-3, 2.0), (5e-3, -1.0)))
    plant = _no_flux_plant(prof, 800.0)
    w0 = plant.sample().omega_m
    j = plant.params.j
    for k in range(1, 81):
        plant.advance([0], [TS_NS])
        t = k * TS
        # ∫ T_load dt from 0 to t, piecewise
        ramp = min(max(t - 1e-3, 0.0), 2e-3)
        integral = 500.0 * ramp**2 + 2.0 * max(min(t, 5e-3) - 3e-3, 0.0) - 1.0 * max(t - 5e-3, 0.0)
        assert plant.sample().omega_m == pytest.approx(w0 - integral / j, rel=1e-12, abs=1e-9), k


def test_viscous_friction_alone_decays_speed_exponentially() -> None:
    plant = _no_flux_plant(LoadProfile.constant(0.0), 1200.0, b=0.013)
    w0 = plant.sample().omega_m
    for _ in range(100):
        plant.advance([0], [TS_NS])
    tau = plant.params.j / 0.013  # 0.1 s
    # trapezoidal (Crank–Nicolson) update: second order, 5 µs pieces → tiny error
    assert plant.sample().omega_m == pytest.approx(w0 * math.exp(-100 * TS / tau), rel=1e-8)


def test_ramp_ending_inside_a_period() -> None:
    """A profile breakpoint inside a period (ramp end at 150 µs) is honoured by the kernel."""
    plant = _no_flux_plant(LoadProfile(((0.0, 0.0), (150e-6, 1.0))), 1000.0)
    w0 = plant.sample().omega_m
    for _ in range(3):
        plant.advance([0], [TS_NS])
    integral = 0.5 * 150e-6 * 1.0 + 150e-6 * 1.0  # ∫ over [0, 300 µs]
    assert plant.sample().omega_m == pytest.approx(w0 - integral / plant.params.j, rel=1e-6)


def test_inertia_mode_per_period_error_against_coupled_reference() -> None:
    """Electrical + mechanical ODE solved together by scipy, restarted from the plant state each period."""
    params = load_motor("niu2020-ipmsm", {"b": 1e-3})
    load = 2.0
    plant = Plant(params, TS, InertiaMechanics(LoadProfile.constant(load), 1500.0), trace_dt_s=None)
    rng = np.random.default_rng(5)
    worst_i = worst_w = 0.0
    for code in rng.integers(0, 8, 200):
        s0 = plant.sample()
        va, vb = stator_voltage(int(code), params.vdc)

        def rhs(_t: float, y: np.ndarray, va: float = va, vb: float = vb) -> list[float]:
            i_d, i_q, th, w = y
            w_e = params.pole_pairs * w
            vd = va * math.cos(th) + vb * math.sin(th)
            vq = -va * math.sin(th) + vb * math.cos(th)
            return [(vd - params.rs * i_d + w_e * params.lq * i_q) / params.ld,
                    (vq - params.rs * i_q - w_e * params.ld * i_d - w_e * params.psi_f) / params.lq,
                    w_e, (params.torque_nm(i_d, i_q) - load - params.b * w) / params.j]

        ref = solve_ivp(rhs, (0.0, TS), [s0.i_d, s0.i_q, s0.theta_e, s0.omega_m], method="DOP853",
                        rtol=1e-11, atol=1e-12).y[:, -1]
        plant.advance([int(code)], [TS_NS])
        s1 = plant.sample()
        worst_i = max(worst_i, abs(s1.i_d - ref[0]), abs(s1.i_q - ref[1]))
        worst_w = max(worst_w, abs(s1.omega_m - ref[3]))
    assert worst_i < 1e-3  # measured ≈ 1.5e-4 A with the default 5 µs pieces
    assert worst_w < 1e-4  # rad/s; measured ≈ 5e-6


def test_load_step_inside_a_period_takes_effect_at_its_time() -> None:
    plant = _no_flux_plant(LoadProfile.steps(0.0, [(130e-6, 2.0)]), 1000.0)
    w0 = plant.sample().omega_m
    for _ in range(3):
        plant.advance([0], [TS_NS])
    integral = 2.0 * (300e-6 - 130e-6)
    assert plant.sample().omega_m == pytest.approx(w0 - integral / plant.params.j, rel=1e-6)
