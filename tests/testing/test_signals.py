"""Signal assertions and stepinfo on synthetic signals: bands, windows, messages, plots; stepinfo against the
exact figures of a second-order step response."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

from pmsm_hil.testing import (
    Signal,
    SignalAssertionError,
    assert_below,
    assert_is_constant,
    assert_settles,
    stepinfo,
)
from pmsm_hil.testing.report import PLOT_PROPERTY, Reporter

TS = 1e-4


def _sig(y: list[float] | np.ndarray, name: str = "x", unit: str = "A", reporter: Reporter | None = None) -> Signal:
    y = np.asarray(y, dtype=float)
    return Signal(name, np.arange(len(y)) * TS, y, unit, reporter)


values = st.lists(st.floats(-1.0, 1.0, allow_nan=False), min_size=2, max_size=200)


@given(values, st.floats(1.0, 10.0))
def test_is_constant_passes_inside_the_band(ys: list[float], tol: float) -> None:
    assert_is_constant(_sig(ys), around=0.0, tol=tol)
    assert_below(_sig(ys), limit=1.0)


@given(values, st.data())
def test_the_worst_violation_is_named(ys: list[float], data: st.DataObject) -> None:
    i = data.draw(st.integers(0, len(ys) - 1))
    ys[i] = 5.0  # the one sample outside [−2, 2] and above 1.5
    for check in (lambda s: assert_is_constant(s, around=0.0, tol=2.0),
                  lambda s: assert_below(s, limit=1.5)):
        with pytest.raises(SignalAssertionError) as err:
            check(_sig(ys, name="i_q"))
        msg = str(err.value)
        assert "i_q" in msg and "worst 5 A" in msg and f"t = {i * TS:.6g} s" in msg, msg
        assert f"(1 of {len(ys)} samples outside)" in msg


@given(st.floats(0.001, 0.5), st.floats(0.0, 0.02), st.floats(0.05, 0.5))
@settings(max_examples=50)
def test_settles_agrees_with_the_decay(tau: float, within: float, tol: float) -> None:
    """to + e^(−t/τ) settles within `within` to ±tol iff e^(−within/τ) ≤ tol (checked from the samples)."""
    t = np.arange(0, 0.05, TS)
    sig = Signal("speed_rpm", t, 100.0 + np.exp(-t / tau), "rpm")
    after = sig.y[t >= within] - 100.0
    if after.max() <= tol:
        assert_settles(sig, to=100.0, tol=tol, within=within)
    else:
        with pytest.raises(SignalAssertionError, match=r"speed_rpm not within 100 rpm ± .* worst .* at t = "):
            assert_settles(sig, to=100.0, tol=tol, within=within)


def test_windows_and_t0() -> None:
    t = np.arange(0, 1.0, 0.01)
    y = np.where(t < 0.5, 0.0, 10.0)
    sig = Signal("torque_nm", t, y, "N·m")
    assert_is_constant(sig, around=10.0, tol=0.1, during=(0.5, 0.99))
    assert_settles(sig, to=10.0, tol=0.1, within=0.1, t0=0.4)
    with pytest.raises(SignalAssertionError, match=r"during \[0.4, 0.99\] s: worst 0 N·m at t = 0.4 s"):
        assert_is_constant(sig, around=10.0, tol=0.1, during=(0.4, 0.99))
    with pytest.raises(SignalAssertionError, match="before the settling deadline"):
        assert_settles(sig, to=10.0, tol=0.1, within=2.0)
    with pytest.raises(SignalAssertionError, match="no samples during"):
        assert_below(sig, 20.0, during=(2.0, 3.0))
    assert_below(sig, 0.0, during=(0.0, 0.49))


def test_nan_is_a_violation() -> None:
    with pytest.raises(SignalAssertionError, match="worst nan"):
        assert_below(_sig([0.0, math.nan, 0.0]), 1.0)


def test_bad_signals_and_tolerances_are_refused() -> None:
    with pytest.raises(ValueError, match="same length"):
        Signal("x", np.zeros(3), np.zeros(2))
    with pytest.raises(ValueError, match="non-decreasing"):
        Signal("x", np.array([0.0, 2.0, 1.0]), np.zeros(3))
    with pytest.raises(ValueError, match="tol"):
        assert_is_constant(_sig([0.0, 0.0]), 0.0, -1.0)


def test_a_failure_writes_a_plot_and_records_it(tmp_path: Path) -> None:
    recorded: list[tuple[str, object]] = []
    reporter = Reporter(tmp_path / "plots", lambda: lambda name, value: recorded.append((name, value)))
    sig = _sig(np.sin(np.arange(300) * 0.05), name="i_a", reporter=reporter)
    with pytest.raises(SignalAssertionError) as err:
        assert_is_constant(sig, around=0.0, tol=0.5, during=(0.005, 0.02))
    path = Path(recorded[0][1])  # type: ignore[arg-type]
    assert recorded[0][0] == PLOT_PROPERTY and path.is_file() and path.read_bytes()[:4] == b"\x89PNG"
    assert f"plot: {path}" in str(err.value) and path.parent == (tmp_path / "plots").resolve()
    with pytest.raises(SignalAssertionError):
        assert_below(sig, 0.5)
    assert len(recorded) == 2 and recorded[1][1] != recorded[0][1]


# --- stepinfo -----------------------------------------------------------------------------------------
ZETA, WN = 0.4, 50.0
WD = WN * math.sqrt(1 - ZETA**2)


def _second_order(t: np.ndarray | float) -> np.ndarray | float:
    """Unit step response of ωn²/(s² + 2ζωn s + ωn²)."""
    phi = math.acos(ZETA)
    return 1.0 - np.exp(-ZETA * WN * t) / math.sqrt(1 - ZETA**2) * np.sin(WD * t + phi)


def _exact() -> tuple[float, float, float]:
    """Rise time 10–90 %, 2 % settling time [s] and overshoot [%] of `_second_order`, from the formula."""
    tp = math.pi / WD  # peak time: monotonic rise before it
    rise = brentq(lambda t: _second_order(t) - 0.9, 0, tp) - brentq(lambda t: _second_order(t) - 0.1, 0, tp)
    dense = np.linspace(0, 1.0, 2_000_001)
    out = np.flatnonzero(np.abs(_second_order(dense) - 1.0) > 0.02)
    i = int(out[-1])
    edge = 1.02 if _second_order(dense[i]) > 1 else 0.98
    settle = brentq(lambda t: _second_order(t) - edge, dense[i], dense[i + 1])
    return rise, settle, 100.0 * math.exp(-math.pi * ZETA / math.sqrt(1 - ZETA**2))


def test_stepinfo_of_a_second_order_response() -> None:
    t_step, y0, gain = 0.1, 2.0, 3.0
    t = np.arange(0, 1.2, TS)
    y = np.where(t < t_step, y0, y0 + gain * _second_order(np.maximum(t - t_step, 0.0)))
    info = stepinfo(Signal("speed_rpm", t, y, "rpm"), t_step, ref=y0 + gain)
    rise, settle, overshoot = _exact()
    assert info.rise_time_s == pytest.approx(rise, abs=2e-6)  # linear interpolation between samples
    assert info.settling_time_s == pytest.approx(settle, abs=2e-6)
    assert info.overshoot_pct == pytest.approx(overshoot, abs=1e-3)
    assert abs(info.steady_state_error) < 1e-6 and info.initial == pytest.approx(y0)
    assert info.peak_time_s == pytest.approx(t_step + math.pi / WD, abs=TS)


def test_stepinfo_of_a_falling_step_and_of_no_step() -> None:
    t = np.arange(0, 0.5, TS)
    y = 5.0 - 4.0 * (1.0 - np.exp(-np.maximum(t - 0.1, 0) / 0.01))
    info = stepinfo(Signal("x", t, y), 0.1)
    assert info.overshoot_pct == 0.0 and math.isnan(info.steady_state_error)
    assert info.rise_time_s == pytest.approx(0.01 * math.log(9), abs=1e-6)
    assert info.settling_time_s == pytest.approx(0.01 * math.log(50), abs=1e-6)
    flat = stepinfo(Signal("x", t, np.ones_like(t)), 0.1, ref=2.0)
    assert math.isnan(flat.rise_time_s) and flat.steady_state_error == 1.0
    with pytest.raises(ValueError, match="fewer than 2 samples"):
        stepinfo(Signal("x", t, y), 1.0)
