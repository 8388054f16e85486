"""THD from an FFT over an integer number of periods: analytic values for known spectra."""

from __future__ import annotations

import math

import numpy as np
import pytest

from pmsm_hil.hil.metrics import MetricsError, MetricsWindowError, current_thd, fundamental_hz

F1 = 66.0 + 2.0 / 3.0  # 1000 rpm, 4 pole pairs


def _signal(t: np.ndarray) -> np.ndarray:
    return (
        10.0 * np.sin(2 * np.pi * F1 * t + 0.2)
        + 0.5 * np.sin(2 * np.pi * 5 * F1 * t + 0.3)
        + 0.3 * np.sin(2 * np.pi * 7 * F1 * t - 1.0)
        + 0.2 * np.sin(2 * np.pi * 37 * F1 * t)
        + 0.25 * np.sin(2 * np.pi * 5432.1 * t + 0.7)  # interharmonic (switching-like content)
        + 1.5  # DC offset: excluded from both figures
    )


EXPECTED_INT = 100.0 * math.sqrt(0.5**2 + 0.3**2 + 0.2**2) / 10.0
EXPECTED_TOTAL = 100.0 * math.sqrt(0.5**2 + 0.3**2 + 0.2**2 + 0.25**2) / 10.0


def test_fundamental_from_speed() -> None:
    assert fundamental_hz(1000.0 * 2 * math.pi / 60.0, 4) == pytest.approx(F1)
    assert fundamental_hz(-1000.0 * 2 * math.pi / 60.0, 4) == pytest.approx(F1)


@pytest.mark.parametrize("dt", [2e-6, 1.7e-6, 1.3e-6])  # non-integer samples per period
def test_thd_two_ways_match_analytic(dt: float) -> None:
    t = np.arange(0.0, 0.1237, dt)  # window of 8.25 periods: not an integer number
    res = current_thd(t, _signal(t), F1)
    assert res.electrical_periods == 8
    assert res.fundamental_a == pytest.approx(10.0, abs=0.01)
    assert abs(res.thd_pct - EXPECTED_INT) < 0.1
    assert abs(res.thd_total_pct - EXPECTED_TOTAL) < 0.1
    assert res.thd_total_pct > res.thd_pct


def test_thd_pure_sine_is_zero() -> None:
    t = np.arange(0.0, 0.05, 2e-6)
    res = current_thd(t, 3.0 * np.sin(2 * np.pi * F1 * t), F1)
    assert res.thd_pct < 0.01 and res.thd_total_pct < 0.01
    assert res.fundamental_a == pytest.approx(3.0, rel=1e-4)


def test_thd_non_uniform_sampling() -> None:
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(1.0e-6, 2.0e-6, size=80_000))
    res = current_thd(t, _signal(t), F1)
    assert abs(res.thd_pct - EXPECTED_INT) < 0.1
    assert abs(res.thd_total_pct - EXPECTED_TOTAL) < 0.1


def test_thd_harmonic_above_40_counts_only_in_total() -> None:
    t = np.arange(0.0, 0.1, 2e-6)
    x = 10.0 * np.sin(2 * np.pi * F1 * t) + 1.0 * np.sin(2 * np.pi * 45 * F1 * t)
    res = current_thd(t, x, F1)
    assert res.thd_pct < 0.01
    assert res.thd_total_pct == pytest.approx(10.0, abs=0.05)


def test_window_shorter_than_one_period_names_field() -> None:
    t = np.arange(0.0, 0.01, 2e-6)
    with pytest.raises(MetricsWindowError, match=r"trace\.i_b.*shorter than one electrical period"):
        current_thd(t, np.sin(2 * np.pi * F1 * t), F1, field="trace.i_b")


def test_bad_inputs_raise_metrics_error() -> None:
    t = np.arange(0.0, 0.1, 2e-6)
    with pytest.raises(MetricsError, match="fundamental frequency"):
        current_thd(t, np.sin(t), 0.0)
    with pytest.raises(MetricsError, match="non-finite"):
        current_thd(t, np.full_like(t, np.nan), F1)
    with pytest.raises(MetricsError, match="strictly increasing"):
        current_thd(t[::-1], np.sin(t), F1)
