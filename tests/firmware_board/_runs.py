"""Short closed-loop runs at the rated point (1500 rpm, 7 N·m) for the firmware-board tests."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import pytest

from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario


def rated(target: str = "auto", *, settle_s: float = 0.05, duration_s: float = 0.15, **kw: Any) -> RunConfig:
    sc = load_scenario("steady").with_overrides(speed_rpm=1500.0, load_nm=7.0, settle_s=settle_s,
                                                duration_s=duration_s)
    return replace(RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc, controller="mpcc"), target=target, **kw)


def metrics(cfg: RunConfig) -> dict[str, Any]:
    res = run_closed_loop(cfg)
    assert res.metrics["end_code"] == 0, res.metrics["end_reason"]
    return res.metrics


#: metrics of the machinery, not of the firmware's control: wall time, link statistics, execution time
MACHINERY_KEYS = frozenset({"wall_time_s", "loop_rate_hz", "exec_time_us", "exec_time_first_us", "link",
                            "safe_stop_wait_ms", "command_wait_max_us", "total_wall_time_s", "loop_rate_total_hz",
                            "link_spec", "target_link", "link_losses"})
#: record columns of the machinery (the target's own execution time)
MACHINERY_COLUMNS = frozenset({"exec_time_ns", "exec_split_ns"})


def assert_holds_rated(m: dict[str, Any]) -> None:
    """A firmware's run at the rated point: no DUT violation, speed within 0.5 %, torque within 1 %, ripple RMS
    below 0.2 N·m."""
    assert m["dut_violations"] == 0
    assert m["speed_mean_rpm"] == pytest.approx(1500.0, rel=0.005)
    assert m["torque_mean_nm"] == pytest.approx(7.0, rel=0.01)
    assert m["torque_ripple_rms_nm"] < 0.2


def assert_like(m: dict[str, Any], ref: dict[str, Any]) -> None:
    """The acceptance: speed within 0.5 %, torque mean within 1 %, ripple RMS within 10 %."""
    assert abs(m["speed_mean_rpm"] - ref["speed_mean_rpm"]) <= 0.005 * ref["speed_mean_rpm"]
    assert abs(m["torque_mean_nm"] - ref["torque_mean_nm"]) <= 0.01 * abs(ref["torque_mean_nm"])
    assert abs(m["torque_ripple_rms_nm"] - ref["torque_ripple_rms_nm"]) <= 0.10 * ref["torque_ripple_rms_nm"]
