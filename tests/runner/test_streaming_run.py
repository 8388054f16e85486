"""A run streams its records: a run longer than the kept-records limit keeps none in memory, its log holds
every period and the whole window trace, and the metrics computed while it ran equal those computed
afterwards from the log."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.hil.metrics import compute_run_metrics
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runlog.reader import read_frames, read_periods, read_trace
from pmsm_hil.hil.runner import recorder
from pmsm_hil.hil.runner.recorder import RecordsNotKeptError
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario

DETERMINISTIC = ("torque_mean_nm", "torque_ripple_rms_nm", "torque_ripple_pp_nm", "speed_mean_rpm",
                 "current_thd_pct", "current_thd_total_pct", "current_fundamental_a", "switching_freq_khz",
                 "switching_freq_intra_khz", "candidates_evaluated_mean", "narrow_pulses", "torque_error_mean_nm")


def test_long_run_streams_and_its_log_gives_the_same_metrics(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(recorder, "KEEP_PERIODS_MAX", 1500)  # this run of 3500 periods counts as long
    sc = load_scenario("steady").with_overrides(speed_rpm=1500.0, load_nm=7.0, settle_s=0.05, duration_s=0.3)
    cfg = RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc, controller="mpcc", link="virtual",
                    target="inproc", mode="lockstep", out_dir=tmp_path / "run", log_trace=True)
    res = run_closed_loop(cfg)
    assert res.metrics["end_code"] == 0
    with pytest.raises(RecordsNotKeptError, match="streamed to the log"):
        res.outcome.periods.all()
    assert res.mcap_path is not None
    periods = read_periods(res.mcap_path)
    assert len(periods) == res.metrics["total_periods"] == 3500
    np.testing.assert_array_equal(periods["seq"], np.arange(3500))
    frames = read_frames(res.mcap_path)
    assert len(frames) >= 2 * 3500  # a Measurement and a Command per period, plus set-up and the safe stop
    trace = read_trace(res.mcap_path)
    assert np.all(np.diff(trace["t"]) > 0) and trace["t"][0] >= 0.05 - 1e-9
    window = periods[500:]
    offline = compute_run_metrics(window, trace, ts_s=cfg.ts_s, pole_pairs=cfg.motor.pole_pairs,
                                  wall_time_s=1.0, link_stats={}, deadline_misses=0)
    for key in DETERMINISTIC:
        assert res.metrics[key] == pytest.approx(offline[key], rel=1e-12), key
    for q in ("median", "p99", "max"):
        assert res.metrics["exec_time_us"][q] == offline["exec_time_us"][q]
    # the in-memory trace is the THD span: here the whole 0.3 s window, equal to the logged one
    np.testing.assert_array_equal(res.outcome.trace["i_a"], trace["i_a"])


def test_short_run_keeps_its_records() -> None:
    sc = load_scenario("steady").with_overrides(speed_rpm=1000.0, load_nm=3.0, settle_s=0.0, duration_s=0.15)
    cfg = RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc, controller="mpcc", link="virtual",
                    target="inproc", mode="lockstep", out_dir=None)
    res = run_closed_loop(cfg)
    periods = res.outcome.periods.all()
    assert len(periods) == 1500
    np.testing.assert_array_equal(periods["seq"], np.arange(1500))
