"""Two masses on an elastic shaft: a mechanics variant (src/pmsm_hil/hil/kernels/mechanics.c) that no machine kernel
knows of. Its free response turns at the torsional resonance sqrt(k·(J1+J2)/(J1·J2)) and decays at c·(J1+J2)/(2·J1·J2);
with a very stiff shaft a machine's run equals the one-mass run of the summed inertia."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil import _plant_native
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.im_plant import ImPlant
from pmsm_hil.hil.mechanics import InertiaMechanics, LoadProfile, TwoMassMechanics
from pmsm_hil.hil.plant import Plant
from pmsm_hil.hil.plant_base import PlantBase
from pmsm_hil.hil.presets_loader import load_motor

ffi, lib = _plant_native.ffi, _plant_native.lib
TS = 100e-6
TS_NS = 100_000


def _free_response(j1: float, j2: float, k: float, c: float, twist0: float, h: float, steps: int) -> np.ndarray:
    """(t, omega_m, omega_l, twist) rows of the shaft released from a twist, no torque on either mass."""
    p = ffi.new("mech_params_t *")
    p.mode, p.j, p.b, p.j_load, p.k_shaft, p.c_shaft = lib.MECH_TWO_MASS, j1, 0.0, j2, k, c
    s = ffi.new("mech_state_t *")
    s.twist = twist0
    rows = np.empty((steps + 1, 4))
    rows[0] = (0.0, s.omega_m, s.omega_l, s.twist)
    for n in range(1, steps + 1):
        lib.mech_step(p, s, h, 0.0, 0.0, 0.0)
        rows[n] = (n * h, s.omega_m, s.omega_l, s.twist)
    return rows


def _crossing_times(t: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Times of the downward and upward zero crossings of x(t), linearly interpolated."""
    idx = np.nonzero(np.signbit(x[:-1]) != np.signbit(x[1:]))[0]
    return t[idx] - x[idx] * (t[idx + 1] - t[idx]) / (x[idx + 1] - x[idx])


def test_free_response_turns_at_the_torsional_resonance() -> None:
    j1, j2, k = 1.3e-3, 3.9e-3, 60.0
    omega_r = math.sqrt(k * (j1 + j2) / (j1 * j2))  # 248 rad/s, 39.5 Hz
    rows = _free_response(j1, j2, k, 0.0, 0.01, 5e-6, 40_000)  # 0.2 s: 7.9 periods
    crossings = _crossing_times(rows[:, 0], rows[:, 3])
    assert len(crossings) >= 14
    half_periods = np.diff(crossings)
    assert float(np.mean(half_periods)) == pytest.approx(math.pi / omega_r, rel=1e-5)
    # no damping: the amplitude stays, the momentum J1·w1 + J2·w2 stays 0
    assert float(np.max(np.abs(rows[-8000:, 3]))) == pytest.approx(0.01, rel=1e-3)
    assert float(np.max(np.abs(j1 * rows[:, 1] + j2 * rows[:, 2]))) < 1e-15
    # the motor mass swings with the larger amplitude: |w1| / |w2| = J2 / J1
    assert float(np.max(np.abs(rows[:, 1])) / np.max(np.abs(rows[:, 2]))) == pytest.approx(j2 / j1, rel=1e-6)


def test_shaft_damping_decays_the_swing_at_its_rate() -> None:
    j1, j2, k, c = 1.3e-3, 3.9e-3, 60.0, 0.02
    sigma = c * (j1 + j2) / (2.0 * j1 * j2)  # 10.3 1/s
    rows = _free_response(j1, j2, k, c, 0.01, 5e-6, 40_000)
    t, twist = rows[:, 0], rows[:, 3]
    peaks = [i for i in range(1, len(twist) - 1) if twist[i - 1] < twist[i] >= twist[i + 1] and twist[i] > 0]
    rate = -np.polyfit(t[peaks], np.log(twist[peaks]), 1)[0]
    assert float(rate) == pytest.approx(sigma, rel=1e-3)


def _zero_vector_run(plant: PlantBase, periods: int) -> np.ndarray:
    """Speed [rad/s] at each period start of a short-circuit braking run."""
    speeds = [plant.sample().omega_m]
    for _ in range(periods):
        plant.advance([0], [TS_NS])
        speeds.append(plant.sample().omega_m)
    return np.asarray(speeds)


@pytest.mark.parametrize("motor", ["niu2020-ipmsm", "im-2k2"])
def test_a_stiff_shaft_equals_one_mass_of_the_summed_inertia(motor: str) -> None:
    """Short-circuit braking from 1500 rpm with a load step: a shaft of 1e8 N·m/rad between 30 % and 70 % of the
    machine's inertia follows the one-mass run within 1e-3 of its speed change; the shaft carries the load's share
    of the torque, k·twist = 0.3·T_load + 0.7·Te."""
    params = load_motor(motor)
    plant_class: Any = ImPlant if motor == "im-2k2" else Plant
    load = LoadProfile.steps(1.0, [(0.01, 3.0)])
    one = _zero_vector_run(plant_class(params, TS, InertiaMechanics(load, 1500.0), trace_dt_s=None), 300)
    two_mass = TwoMassMechanics(load, j_motor=0.3 * params.j, j_load=0.7 * params.j, k_shaft=1e8, c_shaft=50.0,
                                initial_speed_rpm=1500.0)
    plant = plant_class(params, TS, two_mass, trace_dt_s=None)
    two = _zero_vector_run(plant, 300)
    change = abs(one[-1] - one[0])
    assert change > 1.0  # the speed moved
    assert float(np.max(np.abs(two - one))) < 1e-3 * change
    assert abs(two[-1] - one[-1]) < 1e-6 * one[0]
    assert plant.load_speed == pytest.approx(two[-1], abs=1e-6 * one[0])
    shaft_torque = two_mass.k_shaft * plant.shaft_twist
    assert shaft_torque == pytest.approx(0.3 * 3.0 + 0.7 * plant.sample().torque, rel=1e-2, abs=1e-3)


def test_bad_two_mass_values_name_the_field() -> None:
    with pytest.raises(ParameterError, match="k_shaft"):
        TwoMassMechanics(LoadProfile.constant(0.0), 1e-3, 1e-3, 0.0)
    with pytest.raises(ParameterError, match="c_shaft"):
        TwoMassMechanics(LoadProfile.constant(0.0), 1e-3, 1e-3, 1.0, -1.0)
    with pytest.raises(ParameterError, match="j_load"):
        TwoMassMechanics(LoadProfile.constant(0.0), 1e-3, math.nan, 1.0)
