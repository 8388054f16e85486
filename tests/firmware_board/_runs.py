"""Short closed-loop runs at the rated point (1500 rpm, 7 N·m) for the firmware-board tests."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

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


def assert_like(m: dict[str, Any], ref: dict[str, Any]) -> None:
    """The acceptance: speed within 0.5 %, torque mean within 1 %, ripple RMS within 10 %."""
    assert abs(m["speed_mean_rpm"] - ref["speed_mean_rpm"]) <= 0.005 * ref["speed_mean_rpm"]
    assert abs(m["torque_mean_nm"] - ref["torque_mean_nm"]) <= 0.01 * abs(ref["torque_mean_nm"])
    assert abs(m["torque_ripple_rms_nm"] - ref["torque_ripple_rms_nm"]) <= 0.10 * ref["torque_ripple_rms_nm"]
