"""The harmonic metrics take the stator frequency measured from the currents (slip included), and are not
applicable, with the reason, over a span whose fundamental changes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pmsm_hil.hil.metrics import compute_run_metrics
from pmsm_hil.hil.metrics.stator_frequency import MAX_CHANGE_PCT, stator_frequency
from tests.metrics._signals import make_periods, make_trace, three_phase

TS = 100e-6
P = 2
ARGS = {"ts_s": TS, "pole_pairs": P, "wall_time_s": 1.0, "link_stats": {}, "deadline_misses": 0}


def _ripple(t: np.ndarray) -> np.ndarray:
    """Switching-like ripple: a 10 kHz triangle of 0.3 A."""
    return 0.3 * (2.0 * np.abs(2.0 * ((t * 10e3) % 1.0) - 1.0) - 1.0)


@pytest.mark.parametrize("f1", [7.0, 33.9, 250.0, -47.0])
def test_the_frequency_of_a_balanced_set_is_measured(f1: float) -> None:
    t = np.arange(0.0, 0.3, 2e-6)
    a, b, c = three_phase(t, f1, {1: 5.0, 5: 0.3, 7: 0.2})
    got = stator_frequency(t, a + _ripple(t), b + _ripple(t), c + _ripple(t))
    assert got is not None and got.stationary
    assert got.hz == pytest.approx(abs(f1), rel=1e-4)


def test_an_induction_machine_fundamental_is_the_stator_frequency_not_the_rotor_one() -> None:
    """Rotor at 1000 rpm (p = 2: 33.3 Hz electrical), stator at 35.1 Hz (slip 1.8 Hz): the fundamental, its
    amplitude and THD are those of the stator currents."""
    omega_m = 1000.0 * 2.0 * math.pi / 60.0
    f_stator = P * omega_m / (2.0 * math.pi) + 1.8
    tr = make_trace(0.25, 2e-6, omega_m)
    tr["i_a"], tr["i_b"], tr["i_c"] = three_phase(tr["t"], f_stator, {1: 7.0, 5: 0.35, 7: 0.21})
    tr["torque"] = 10.0
    p = make_periods(round(0.25 / TS), TS)
    m = compute_run_metrics(p, tr, **ARGS)
    assert m["current_fundamental_hz"] == pytest.approx(f_stator, rel=1e-4)
    assert m["current_rotor_electrical_hz"] == pytest.approx(P * omega_m / (2.0 * math.pi))
    assert m["current_fundamental_a"] == pytest.approx(7.0, rel=2e-3)
    expected = 100.0 * math.hypot(0.35, 0.21) / 7.0
    assert m["current_thd_pct"] == pytest.approx(expected, abs=0.05)
    assert m["current_thd_total_pct"] == pytest.approx(expected, abs=0.1)
    assert m["not_applicable"] == {}


def test_a_changing_fundamental_makes_the_harmonic_metrics_not_applicable() -> None:
    """A speed step inside the span (1000 → 1500 rpm electrical equivalent): no THD number, the reason given."""
    tr = make_trace(0.3, 2e-6, 120.0)
    t = tr["t"]
    f = np.where(t < 0.1, 33.3, 50.0)
    phase = 2.0 * math.pi * np.cumsum(f) * 2e-6
    for name, shift in (("i_a", 0.0), ("i_b", -2.0 * math.pi / 3.0), ("i_c", 2.0 * math.pi / 3.0)):
        tr[name] = 6.0 * np.sin(phase + shift)
    tr["torque"] = 5.0
    m = compute_run_metrics(make_periods(round(0.3 / TS), TS), tr, **ARGS)
    for key in ("current_thd_pct", "current_thd_total_pct", "current_fundamental_a", "current_fundamental_hz",
                "current_thd_phases_pct", "current_distortion_rms_a"):
        assert m[key] is None
        assert "changes by" in m["not_applicable"][key]
    assert m["current_fundamental_change_pct"] > MAX_CHANGE_PCT
    assert m["current_thd_note"] == m["not_applicable"]["current_thd_pct"]
