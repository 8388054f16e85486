"""Dual three-phase closed loop: Plant6, Measurement6 frames, six-leg switching count, x-y metrics."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario


def _cfg(controller: str, link: str = "virtual") -> RunConfig:
    sc = load_scenario("steady").with_overrides(speed_rpm=1500.0, load_nm=40.0, settle_s=0.03, duration_s=0.03)
    return RunConfig(motor=load_motor("zhang2021-dtpmsm"), scenario=sc, controller=controller, link=link)


@pytest.mark.parametrize("profile", ["virtual", "virtual,fd=false"])
def test_mptc2_runs_the_six_phase_plant_over_both_frame_profiles(profile: str) -> None:
    res = run_closed_loop(_cfg("mptc2", profile))
    m = res.metrics
    assert m["end_reason"] == "completed"
    assert abs(m["torque_mean_nm"] - 40.0) < 4.0
    assert m["candidates_evaluated_mean"] == 13
    periods = res.outcome.periods.all()
    assert np.isfinite(periods["i_u"]).all() and np.isfinite(periods["i_x"]).all()
    # the second set carries current: it is not a three-phase run in disguise
    assert np.abs(periods["i_u"]).max() > 10.0
    assert m["xy_current_rms_a"] > 0.0
    assert m["current_distortion_rms_a"] > 0.0


def test_six_legs_counted_for_the_switching_frequency() -> None:
    res = run_closed_loop(_cfg("mptc3"))
    periods = res.outcome.periods.all()[res.outcome.window_start_period:]
    expected = periods["leg_transitions"].sum() / (2 * 6 * len(periods) * 1e-4) / 1e3
    assert res.metrics["switching_freq_khz"] == pytest.approx(expected)
    assert res.metrics["candidates_evaluated_mean"] == 6


def test_three_phase_runs_leave_the_six_phase_fields_empty() -> None:
    sc = load_scenario("steady").with_overrides(settle_s=0.0, duration_s=0.01)
    res = run_closed_loop(RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc))
    periods = res.outcome.periods.all()
    assert np.isnan(periods["i_u"]).all() and np.isnan(periods["i_y"]).all()
    assert "xy_current_rms_a" not in res.metrics


def test_six_phase_overcurrent_trips_into_the_safe_state() -> None:
    cfg = replace(_cfg("mptc2"), motor=load_motor("zhang2021-dtpmsm", {"i_trip": 20.0}))
    m = run_closed_loop(cfg).metrics
    assert m["end_code"] == 3 and "overcurrent" in m["end_reason"] and m["target_disabled"] is True
