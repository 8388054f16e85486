"""Closed loop in lockstep with the in-process sim target on the python-can virtual bus."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import pytest

from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario

_WALL_KEYS = {"wall_time_s", "loop_rate_hz", "total_wall_time_s", "loop_rate_total_hz", "exec_time_us",
              "exec_split_us", "exec_time_first_us", "safe_stop_wait_ms"}


def _cfg(**scenario: Any) -> RunConfig:
    sc = load_scenario(scenario.pop("name", "steady")).with_overrides(**scenario)
    return RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc)


def test_default_steady_state_holds_speed_and_torque() -> None:
    res = run_closed_loop(_cfg(duration_s=0.1))
    m = res.metrics
    assert m["end_reason"] == "completed"
    assert abs(m["speed_mean_rpm"] - 1500.0) <= 15.0
    assert abs(m["torque_mean_nm"] - 7.0) <= 0.14
    assert m["candidates_evaluated_mean"] == 7
    assert 0.5 < m["switching_freq_khz"] < 5.0
    assert m["current_thd_pct"] is not None and 0.0 < m["current_thd_pct"] < m["current_thd_total_pct"]
    assert m["link"]["frames_tx"] > 0 and m["link"]["lost"] == 0


def test_lockstep_reruns_are_identical() -> None:
    a = run_closed_loop(_cfg(settle_s=0.02, duration_s=0.03)).metrics
    b = run_closed_loop(_cfg(settle_s=0.02, duration_s=0.03)).metrics
    strip = lambda m: {k: v for k, v in m.items() if k not in _WALL_KEYS}  # noqa: E731
    assert strip(a) == strip(b)


def test_speed_step_reaches_new_speed() -> None:
    res = run_closed_loop(_cfg(name="speed-step", settle_s=0.05, speed_step_s=0.06, duration_s=0.15))
    periods = res.outcome.periods.all()
    last = periods["omega_m"][-100:].mean() * 60 / (2 * 3.141592653589793)
    assert abs(last - 1500.0) < 15.0
    assert periods["omega_m"][500] * 60 / (2 * 3.141592653589793) == pytest.approx(1000.0, abs=15.0)


def test_acceleration_from_standstill_respects_torque_limit() -> None:
    res = run_closed_loop(_cfg(name="accel", duration_s=0.1))
    periods = res.outcome.periods.all()
    rpm = periods["omega_m"] * 60 / (2 * 3.141592653589793)
    assert rpm[0] == 0.0
    assert rpm[-1] > 1000.0
    assert periods["torque_ref"][10:].max() <= 10.0 + 1e-3  # the paper's ~10 N·m starting torque


def test_load_step_recovers() -> None:
    res = run_closed_loop(_cfg(name="load-step", settle_s=0.05, load_step_s=0.06, duration_s=0.1))
    periods = res.outcome.periods.all()
    assert periods["load_torque"][0] == 0.0 and periods["load_torque"][-1] == 7.0
    assert periods["torque"][-200:].mean() == pytest.approx(7.0, abs=0.5)


def test_silent_target_trips_watchdog_into_safe_state() -> None:
    cfg = replace(_cfg(settle_s=0.0, duration_s=0.05), watchdog_periods=5, tolerate=1000)
    res = run_closed_loop(cfg, silent_after=100)
    assert res.outcome.safe_state
    assert res.outcome.end_reason.startswith("watchdog: target silent for 5 periods")
    assert res.outcome.completed_periods == 105
    assert res.metrics["link"]["lost"] == 5


def test_overcurrent_trip_ends_run_safely() -> None:
    cfg = replace(_cfg(settle_s=0.0, duration_s=0.05), motor=load_motor("niu2020-ipmsm", {"i_trip": 3.0}))
    res = run_closed_loop(cfg)
    assert res.outcome.safe_state
    assert "overcurrent" in res.outcome.end_reason


def test_silent_target_is_a_dut_violation_by_default() -> None:
    res = run_closed_loop(replace(_cfg(settle_s=0.0, duration_s=0.05), watchdog_periods=5), silent_after=100)
    m = res.metrics
    assert m["end_code"] == 4 and m["end_period"] == 100 and m["dut_violations"] == 1
    assert m["end_reason"].startswith("DUT contract violation at period 100 (seq 100): missing:")
    assert m["dut_violation_list"][0]["rule"] == "missing" and m["target_disabled"] is True
