"""The saturated flux-map preset closed loop (issue 28 item 3, "runs mpcc and foc closed loop at rated load"): the
operating-range test's steady scenario and tolerances (tests/runner/test_operating_range.py: mean speed within 1 %
of the reference, mean torque within max(2 %, 0.05 N·m) of the load) at the rated 7 N·m, at rated and one fifth of
rated speed; and the C period loop runs the kind as the Python loop does, record for record."""

from __future__ import annotations

import pytest
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario

from tests.runner.test_operating_range import SPEED_TOL_PCT, TORQUE_TOL_MIN_NM, TORQUE_TOL_REL, TRACE_DT_S

MOTOR = "niu2020-ipmsm-sat"
RATED_NM = 7.0
TIMING_FIELDS = {"exec_time_ns", "exec_split_ns"}


@pytest.mark.parametrize("controller", ["mpcc", "foc"])
@pytest.mark.parametrize("speed_rpm", [300.0, 1500.0])
def test_the_saturated_map_holds_rated_load(controller: str, speed_rpm: float) -> None:
    sc = load_scenario("steady").with_overrides(speed_rpm=speed_rpm, load_nm=RATED_NM, settle_s=0.05,
                                                duration_s=0.1)
    m = run_closed_loop(RunConfig(motor=load_motor(MOTOR), scenario=sc, controller=controller,
                                  trace_dt_s=TRACE_DT_S)).metrics
    speed_pct = 100.0 * (m["speed_mean_rpm"] - speed_rpm) / speed_rpm
    torque_err = m["torque_mean_nm"] - RATED_NM
    print(f"{controller} {speed_rpm:.0f} rpm 7 N·m: speed {speed_pct:+.3f} %, torque {torque_err:+.4f} N·m, "
          f"ripple {m['torque_ripple_rms_nm']:.3f} N·m RMS, loop {m['loop']}")
    assert m["end_reason"] == "completed" and m["loop"] == "native"
    assert abs(speed_pct) <= SPEED_TOL_PCT
    assert abs(torque_err) <= max(TORQUE_TOL_REL * RATED_NM, TORQUE_TOL_MIN_NM)


def test_the_c_loop_runs_the_kind_as_the_python_loop() -> None:
    sc = load_scenario("dyno-steady").with_overrides(settle_s=0.01, duration_s=0.01, load_nm=3.0)
    runs = [run_closed_loop(RunConfig(motor=load_motor(MOTOR), scenario=sc, controller="mpcc", loop=loop))
            for loop in ("python", "native")]
    py, na = (r.outcome.periods.all() for r in runs)
    assert py.shape == na.shape and py.shape[0] > 100
    for name in py.dtype.names or ():
        if name not in TIMING_FIELDS:
            assert py[name].tobytes() == na[name].tobytes(), name
    assert abs(na["i_q"][-50:].mean()) > 1.0
