"""Duty cycles → switching sequence (src/pmsm_hil/hil/pwm.py and its C twin src/pmsm_hil/hil/runner/c/pwm_duty.c, the
native loop's command path): the switching instants equal a brute-force carrier comparison (the triangle evaluated at
every ns, exact rational arithmetic), both implementations give the same ns, and dead time / minimum pulse act on duty
sequences as on any other."""

from __future__ import annotations

import random
from fractions import Fraction
from itertools import pairwise

import numpy as np
import pytest

from pmsm_hil.hil import _loop_native  # type: ignore[attr-defined]
from pmsm_hil.hil.mechanics import DynoMechanics
from pmsm_hil.hil.plant import Plant
from pmsm_hil.hil.plant6 import Plant6
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.pwm import DUTY_FULL, FALLING, RISING, SINGLE, carrier_half, duty_sequence, leg_intervals

HALVES = (SINGLE, RISING, FALLING)


def _carrier(t: Fraction, ts: int, half: int) -> Fraction:
    """The triangle counter 0 (valley) .. 1 (peak) at time t [ns] of the period."""
    if half == SINGLE:
        x = 2 * t / ts
        return x if x <= 1 else 2 - x
    return t / ts if half == RISING else 1 - t / ts


def _brute_levels(raw: list[int], ts: int, half: int) -> np.ndarray:
    """Per leg (rows), the gate level in each ns [n, n+1): the carrier compared at the ns's middle t = n + 1/2
    (c(t) > 1 − d, d = raw/DUTY_FULL), exactly: both sides multiplied by 2·ts·DUTY_FULL, in integers
    (`_carrier` in rationals is the same comparison; `test_the_integer_comparison_is_the_rational_one`)."""
    m = 2 * np.arange(ts, dtype=np.int64) + 1  # 2t
    # single: c = 2t/ts up to the peak, 2 − 2t/ts after it (c·2·ts = 2·2t or 4·ts − 2·2t); rising: c = t/ts
    # (c·2·ts = 2t); falling: c = 1 − t/ts (c·2·ts = 2·ts − 2t)
    rising_or_falling = m if half == RISING else 2 * ts - m
    c2ts = np.where(m <= ts, 2 * m, 4 * ts - 2 * m) if half == SINGLE else rising_or_falling
    thr2ts = 2 * ts * (DUTY_FULL - np.asarray(raw, dtype=np.int64))  # (1 − d)·2·ts·DUTY_FULL
    return (c2ts[None, :] * DUTY_FULL > thr2ts[:, None]).astype(np.int8)


def _levels_of(states: tuple[int, ...], durs: tuple[int, ...], legs: int) -> np.ndarray:
    """Per leg (rows), the gate level in each ns of the switching sequence."""
    st = np.repeat(np.asarray(states, dtype=np.int64), durs)
    return np.stack([(st >> (legs - 1 - leg)) & 1 for leg in range(legs)]).astype(np.int8)


def test_the_integer_comparison_is_the_rational_one() -> None:
    rng = random.Random(5)
    for half in HALVES:
        for ts in (997, 1000, 2001):
            raw = [0, DUTY_FULL, *(rng.randrange(DUTY_FULL + 1) for _ in range(4))]
            rational = [[1 if _carrier(Fraction(2 * n + 1, 2), ts, half) > 1 - Fraction(r, DUTY_FULL) else 0
                         for n in range(ts)] for r in raw]
            assert _brute_levels(raw, ts, half).tolist() == rational


def _exact_edges(r: int, ts: int, half: int) -> list[Fraction]:
    low = Fraction(DUTY_FULL - r, DUTY_FULL)
    if half == SINGLE:
        return [low * ts / 2, ts - low * ts / 2]
    return [low * ts] if half == RISING else [ts - low * ts]


@pytest.mark.parametrize("legs", [3, 6])
@pytest.mark.parametrize("half", HALVES)
def test_switching_instants_equal_a_brute_force_carrier_comparison(legs: int, half: int) -> None:
    rng = random.Random(27 + legs + 10 * half)
    for trial in range(40):
        ts = rng.choice([997, 1000, 2001, 4000])
        raw = [rng.choice([0, DUTY_FULL, rng.randrange(DUTY_FULL + 1), rng.randrange(DUTY_FULL + 1)])
               for _ in range(legs)]
        states, durs = duty_sequence(raw, ts, half)
        assert sum(durs) == ts and all(d > 0 for d in durs), (raw, ts)
        assert len(states) <= 2 * legs + 1
        assert all(a != b for a, b in pairwise(states))  # merged: every boundary is an edge
        got, brute = _levels_of(states, durs, legs), _brute_levels(raw, ts, half)
        for leg, n in zip(*np.nonzero(got != brute), strict=True):
            # only the ns an exact instant falls in may differ (rounding to the ns grid, ≤ 0.5 ns)
            assert any(abs(Fraction(2 * int(n) + 1, 2) - e) <= Fraction(1, 2)
                       for e in _exact_edges(raw[leg], ts, half)), (trial, leg, n, raw, ts)
        for leg, (on, off) in enumerate(leg_intervals(raw, ts, half)):  # each instant within 0.5 ns of the exact one
            exact = _exact_edges(raw[leg], ts, half)
            inside = [t for t in (on, off) if 0 < t < ts]
            for t in inside:
                assert min(abs(t - e) for e in exact) <= Fraction(1, 2)


def test_the_seven_segments_of_three_distinct_duties() -> None:
    """0-x-xy-7-xy-x-0: leg a 0.8, b 0.5, c 0.2 over Ts = 100 µs (a first on, last off)."""
    raw = [round(0.8 * DUTY_FULL), DUTY_FULL // 2, round(0.2 * DUTY_FULL)]
    states, durs = duty_sequence(raw, 100_000)
    assert states == (0b000, 0b100, 0b110, 0b111, 0b110, 0b100, 0b000)
    assert durs == (10_000, 15_000, 15_000, 20_000, 15_000, 15_000, 10_000)
    assert duty_sequence([0, 0, 0], 100_000) == ((0,), (100_000,))
    assert duty_sequence([DUTY_FULL] * 3, 100_000) == ((7,), (100_000,))


def test_double_update_halves_join_into_one_carrier_period() -> None:
    """Rising then falling half = the single-update sequence of a carrier period 2·Ts."""
    raw = [12345, 40000, 65000]
    up = duty_sequence(raw, 50_000, carrier_half("double", 0))
    down = duty_sequence(raw, 50_000, carrier_half("double", 1))
    whole = duty_sequence(raw, 100_000, SINGLE)
    joined_states = up[0] + down[0][1:]
    joined_durs = (*up[1][:-1], up[1][-1] + down[1][0], *down[1][1:])
    assert (joined_states, joined_durs) == whole


def test_the_c_kernel_gives_the_same_ns() -> None:
    ffi, lib = _loop_native.ffi, _loop_native.lib
    rng = random.Random(5)
    raw_c = ffi.new("uint16_t[6]")
    st_c = ffi.new("int32_t[13]")
    du_c = ffi.new("int64_t[13]")
    for _ in range(3000):
        legs = rng.choice([3, 6])
        ts = rng.randrange(1000, 10_000_000)
        half = rng.choice(HALVES)
        raw = [rng.choice([0, DUTY_FULL, rng.randrange(DUTY_FULL + 1)]) for _ in range(legs)]
        for j, r in enumerate(raw):
            raw_c[j] = r
        n = lib.pwm_duty_sequence(legs, raw_c, ts, half, st_c, du_c)
        assert (tuple(st_c[0:n]), tuple(du_c[0:n])) == duty_sequence(raw, ts, half)
    raw_c[1] = DUTY_FULL + 1
    assert lib.pwm_duty_sequence(3, raw_c, 100_000, SINGLE, st_c, du_c) == -2  # a reserved code never applies


def test_min_pulse_and_dead_time_act_on_duty_sequences() -> None:
    """A duty whose pulse (100 ns) is shorter than t_mpw = 200 ns never reaches the gate; a wide one does, with
    the dead time counting its narrow-pulse limit 2·t_dead + t_mpw."""
    motor = load_motor("niu2020-ipmsm").with_values(t_dead=1e-6, t_mpw=200e-9)
    plant = Plant(motor, 100e-6, DynoMechanics(50.0), trace_dt_s=None)
    narrow = [round(0.001 * DUTY_FULL), DUTY_FULL // 2, DUTY_FULL // 2]  # leg a: 100 ns pulse
    st = plant.advance(*duty_sequence(narrow, plant.ts_ns))
    assert st.suppressed_pulses == 1 and st.narrow_pulses >= 1
    assert st.leg_transitions == 4  # legs b and c: on and off; leg a: nothing reached the gate
    wide = [round(0.9 * DUTY_FULL), DUTY_FULL // 2, round(0.1 * DUTY_FULL)]
    st = plant.advance(*duty_sequence(wide, plant.ts_ns))
    assert st.suppressed_pulses == 0 and st.leg_transitions == 6 and st.narrow_pulses == 0


def test_six_duties_drive_the_dual_three_phase_plant() -> None:
    """Six legs, distinct duties: 13 segments, 12 gate transitions in one period."""
    motor = load_motor("zhang2021-dtpmsm")
    plant = Plant6(motor, 100e-6, DynoMechanics(100.0), trace_dt_s=None)
    raw = [round(d * DUTY_FULL) for d in (0.1, 0.25, 0.4, 0.55, 0.7, 0.85)]
    states, durs = duty_sequence(raw, plant.ts_ns)
    assert len(states) == 13
    st = plant.advance(states, durs)
    assert st.leg_transitions == 12
