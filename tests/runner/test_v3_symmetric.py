"""v3_symmetric on zhang2021-dtpmsm at 1500 rpm / 40 N·m (40 ms simulated each): the symmetric G1/2–G2–G1/2
V3 halves the within-period x-y ramp of mptc2 (docs/algorithms/mptc.md, docs/comparisons/zhang2021.md)."""

from __future__ import annotations

import numpy as np
import pytest

from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import RunResult, run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.protocol.ids import ParamId
from pmsm_hil.sim_target.firmware import Firmware, FirmwareConfigError


def _run(symmetric: float) -> RunResult:
    sc = load_scenario("steady").with_overrides(speed_rpm=1500.0, load_nm=40.0, settle_s=0.02, duration_s=0.02)
    return run_closed_loop(RunConfig(motor=load_motor("zhang2021-dtpmsm"), scenario=sc, controller="mptc2",
                                     controller_params={"v3_symmetric": symmetric}))


def test_symmetric_v3_lowers_the_x_y_current_of_mptc2() -> None:
    plain, sym = _run(0.0), _run(1.0)
    assert plain.metrics["end_reason"] == sym.metrics["end_reason"] == "completed"
    assert abs(sym.metrics["torque_mean_nm"] - 40.0) < 3.0
    # two-sub-interval triangle 0 -> 47 A -> 0 (RMS ~23 A with zero vectors); symmetric: half the peak, no mean
    assert plain.metrics["xy_current_rms_a"] > 18.0
    assert sym.metrics["xy_current_rms_a"] < 0.6 * plain.metrics["xy_current_rms_a"]
    assert sym.metrics["current_distortion_rms_a"] < plain.metrics["current_distortion_rms_a"]
    # the price: two more G1 <-> G2 edges per V3 period
    assert sym.metrics["switching_freq_intra_khz"] > 1.5 * plain.metrics["switching_freq_intra_khz"]
    periods = sym.outcome.periods.all()
    v3 = periods["vector_id"] > 0
    assert v3.any() and (periods["mirror"][v3] == 1).all() and (periods["mirror"][~v3] == 0).all()
    assert (plain.outcome.periods.all()["mirror"] == 0).all()
    assert np.abs(periods["i_x"]).max() < 5.0  # sampled at the period edges: x-y volt-seconds still cancel


def test_v3_symmetric_accepts_only_0_or_1() -> None:
    fw = Firmware()
    assert fw.get_param(ParamId.V3_SYMMETRIC) == 0.0
    fw.set_param(ParamId.V3_SYMMETRIC, 1.0)
    assert fw.get_param(ParamId.V3_SYMMETRIC) == 1.0
    for bad in (0.5, 2.0, -1.0):
        with pytest.raises(FirmwareConfigError, match="outside"):
            fw.set_param(ParamId.V3_SYMMETRIC, bad)
    assert fw.get_param(ParamId.V3_SYMMETRIC) == 1.0
