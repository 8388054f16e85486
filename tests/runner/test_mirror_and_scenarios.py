"""Mirrored commands through the closed loop, recorded flags, two-step load scenarios and theta0."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.hil.errors import InputFileError, ParameterError
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.plant_setup import build_plant
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario


def _xiao(controller: str, ideal: bool, **params: float) -> RunConfig:
    motor = load_motor("xiao2023-spmsm")
    if ideal:
        motor = motor.with_values(t_dead=0.0, t_mpw=0.0)
    sc = load_scenario("steady").with_overrides(speed_rpm=1000.0, load_nm=4.0, settle_s=0.03, duration_s=0.05)
    return RunConfig(motor=motor, scenario=sc, controller=controller, controller_params=params)


def test_ideal_3vmpc_sends_mirrored_sequence_at_6_67_khz() -> None:
    res = run_closed_loop(_xiao("3vmpc", ideal=True))
    m = res.metrics
    assert m["end_reason"] == "completed"
    periods = res.outcome.periods.all()[res.outcome.window_start_period:]
    assert np.mean(periods["mirror"]) > 0.95  # every period with two or more distinct states
    # four one-leg transitions inside each period: 4 / (6 · 100 µs)
    assert m["switching_freq_intra_khz"] == pytest.approx(6.67, abs=0.1)
    assert m["switching_freq_khz"] >= m["switching_freq_intra_khz"]
    assert m["narrow_pulses_gated"] == 0 and abs(m["speed_mean_rpm"] - 1000.0) < 10.0


def test_gated_narrow_pulses_are_recorded() -> None:
    m = run_closed_loop(_xiao("3vmpc", ideal=False)).metrics
    assert m["narrow_pulses"] > 0 and 0 <= m["narrow_pulses_gated"] <= m["narrow_pulses"]
    assert run_closed_loop(_xiao("hv-mpfc", ideal=False, t_thr=8e-6)).metrics["narrow_pulses"] == 0


def test_two_load_steps_and_theta0(tmp_path: Path) -> None:
    sc = load_scenario("load-steps")
    prof = sc.load_profile()
    assert [prof.value_and_slope(t)[0] for t in (0.1, 0.25, 0.35)] == [0.0, 4.0, 2.0]
    path = tmp_path / "s.toml"
    for bad in ("[[0.1, 1.0], [0.05, 2.0]]", "[0.1, 1.0]"):  # times going back; not [time, N·m] pairs
        path.write_text(f"load_steps = {bad}\n", encoding="utf-8")
        with pytest.raises(InputFileError, match="load_steps"):
            load_scenario(str(path))
    with pytest.raises(ParameterError, match="theta0_rad"):
        sc.with_overrides(theta0_rad=float("nan"))
    cfg = RunConfig(motor=load_motor("xiao2023-spmsm"), scenario=sc.with_overrides(theta0_rad=1.25),
                    controller="3vmpc")
    assert build_plant(cfg).sample().theta_e == pytest.approx(1.25)
