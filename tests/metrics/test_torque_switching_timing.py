"""Torque ripple (eq. (20)), switching frequency and execution-time statistics on known inputs."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pmsm_hil.hil.metrics import MetricsError, MetricsWindowError, switching_stats, timing_stats, torque_stats
from tests.metrics._signals import make_periods, make_trace


def test_sinusoidal_ripple_rms_is_amplitude_over_sqrt2() -> None:
    tr = make_trace(0.02, 2e-6)
    tr["torque"] = 5.0 + 0.8 * np.sin(2 * np.pi * 1000.0 * tr["t"])
    st = torque_stats(tr)
    assert st.mean_nm == pytest.approx(5.0, abs=1e-9)
    assert st.ripple_rms_nm == pytest.approx(0.8 / math.sqrt(2.0), rel=1e-6)
    assert st.ripple_pp_nm == pytest.approx(1.6, rel=1e-6)


def test_ripple_matches_eq20_sample_formula_for_uniform_samples() -> None:
    rng = np.random.default_rng(3)
    tr = make_trace(0.01, 2e-6)
    tr["torque"] = 2.0 + rng.normal(0.0, 0.3, tr.shape[0])
    eq20 = math.sqrt(float(np.mean((tr["torque"] - tr["torque"].mean()) ** 2)))
    assert torque_stats(tr).ripple_rms_nm == pytest.approx(eq20, rel=1e-3)


def test_empty_trace_is_a_clear_error() -> None:
    with pytest.raises(MetricsWindowError, match="trace"):
        torque_stats(make_trace(0.0, 1e-6)[:0])


def test_three_vector_sequence_four_transitions_gives_6_67_khz() -> None:
    p = make_periods(1000, 100e-6)
    p["leg_transitions"] = 4
    p["boundary_transitions"] = 1
    st = switching_stats(p, ts_s=100e-6, legs=3)
    assert st.freq_khz == pytest.approx(4.0 / (2 * 3 * 100e-6) / 1e3)
    assert st.freq_khz == pytest.approx(6.667, abs=1e-3)
    assert st.freq_intra_khz == pytest.approx(5.0)
    assert st.transitions == 4000 and st.boundary_transitions == 1000


def test_switching_six_legs_and_bad_counts() -> None:
    p = make_periods(10, 50e-6)
    p["leg_transitions"] = 12
    assert switching_stats(p, ts_s=50e-6, legs=6).freq_khz == pytest.approx(12 / (2 * 6 * 50e-6) / 1e3)
    p["boundary_transitions"] = 13
    with pytest.raises(MetricsError, match="boundary_transitions"):
        switching_stats(p, ts_s=50e-6)
    with pytest.raises(MetricsError, match="legs"):
        switching_stats(p, ts_s=50e-6, legs=0)
    with pytest.raises(MetricsError, match="ts_s"):
        switching_stats(p, ts_s=-1.0)


def test_exec_time_statistics() -> None:
    p = make_periods(100, 100e-6)
    p["exec_time_ns"] = np.arange(1, 101) * 1000  # 1..100 µs
    p["exec_split_ns"] = np.array([2000, 3000, 7000])
    p["candidates"] = np.arange(100) % 10
    p["late"][:3] = 1
    p["missed"][:1] = 1
    st = timing_stats(p)
    assert st.exec_median_us == pytest.approx(50.5)
    assert st.exec_p99_us == pytest.approx(99.01)
    assert st.exec_max_us == pytest.approx(100.0)
    assert st.split_median_us == {"measure": 2.0, "reference": 3.0, "predict": 7.0}
    assert st.candidates_mean == pytest.approx(4.5)
    assert (st.late_periods, st.missed_periods) == (3, 1)
