"""Acceptance tests of the reference firmware (mpcc on the niu2020 IPMSM), written as a user writes them for
their own firmware: plain pytest, the `hil` fixture and the assertions of `pmsm_hil.testing`, no other import
from the project. Run them against any target:

    pytest examples/ci --hil-target inproc          # the firmware in-process (default)
    pytest examples/ci --hil-target spawn           # a `hil target` process over UDP
    pytest examples/ci --hil-target external:socketcan:can0 --hil-controller external   # a board

Runs are short (0.15–0.35 s simulated); times are run time [s] from the first period, settling included.
docs/ci.md explains the options, the JUnit output and the failure plots.
"""

from __future__ import annotations

import pytest

from pmsm_hil.testing import (
    assert_below,
    assert_is_constant,
    assert_ripple_below,
    assert_settles,
    assert_thd_below,
    stepinfo,
)

STEP_S = 0.22  # speed-step and load-step scenarios: the step 220 ms into the run


def test_speed_step_1000_to_1500_rpm(hil):
    r = hil.run(scenario="speed-step", settle=0.02, duration=0.33)
    assert r.end_code == 0, r.end_reason
    speed = r.signal("speed_rpm")
    assert_is_constant(speed, around=1000, tol=10, during=(0.1, STEP_S))  # before the step
    info = stepinfo(speed, STEP_S, ref=1500)
    assert info.rise_time_s < 0.03 and info.overshoot_pct < 5.0, info
    assert_settles(speed, to=1500, tol=15, within=0.06, t0=STEP_S)
    assert abs(info.steady_state_error) < 5.0, info


def test_load_step_0_to_7_nm(hil):
    r = hil.run(scenario="load-step", settle=0.02, duration=0.33)
    assert r.end_code == 0, r.end_reason
    speed, torque = r.signal("speed_rpm"), r.signal("torque_nm")
    assert_is_constant(speed, around=1500, tol=100, during=(STEP_S, 0.35))  # the dip stays under 100 rpm
    info = stepinfo(torque, STEP_S, ref=7.0)
    assert info.rise_time_s < 0.005 and abs(info.steady_state_error) < 0.2, info  # torque follows the load
    assert_settles(torque, to=7.0, tol=1.5, within=0.01, t0=STEP_S)  # ripple included
    assert_below(r.signal("i_q"), 40.0)  # no current spike beyond the machine's range


def test_torque_ripple_and_current_thd_at_rated_load(hil):
    r = hil.run(scenario="steady", speed=1500, load=7, settle=0.05, duration=0.1)
    assert r.end_code == 0, r.end_reason
    assert_ripple_below(r, nm=0.5)
    assert_thd_below(r, pct=6.0)


@pytest.mark.parametrize("ld", [0.008, 0.018])  # the firmware's L_d 33 % low / 50 % high (plant: 12 mH)
def test_parameter_mismatch_keeps_speed_and_thd(hil, ld):
    r = hil.run(scenario="steady", settle=0.05, duration=0.1, params={"ld": ld})
    assert r.end_code == 0, r.end_reason
    assert abs(r.metrics["speed_error_pct"]) < 0.5
    assert_thd_below(r, pct=6.0)
    assert_ripple_below(r, nm=0.5)
