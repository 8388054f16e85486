"""A two-mass shaft as a run option (`--shaft two-mass --load-inertia J --shaft-stiffness K --shaft-damping C`, or
the scenario keys): a closed-loop run shows the torsional resonance sqrt(k·(J1+J2)/(J1·J2)) in the logged motor
speed after a load step, a very stiff shaft runs as one mass of the summed inertia, and bad values are refused
with one line naming the field."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.errors import InputFileError, ParameterError
from pmsm_hil.hil.mechanics import TwoMassMechanics
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.plant_setup import build_plant
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario

J_MOTOR = load_motor("niu2020-ipmsm").j  # 1.3e-3 kg·m²
TS = 100e-6
STEP_S = 0.12  # the load step [s], inside the metrics window


def _options(**extra: Any) -> dict[str, Any]:
    """niu2020 under MPCC at 1000 rpm, a 2 N·m load step at STEP_S, 0.1 s settle + 0.15 s window, no log."""
    scenario = {"speed": 1000.0, "load": 2.0, "settle": 0.1, "duration": 0.15}
    return {"motor": "niu2020-ipmsm", "scenario": "load-step", **scenario, "no_log": True, **extra}


def _speeds(options: dict[str, Any], tmp_path: Path) -> tuple[np.ndarray, np.ndarray]:
    """(t [s], motor speed [rad/s]) of each period of a run with a load step at STEP_S."""
    path = tmp_path / "step.toml"
    path.write_text(f'mechanics = "inertia"\nspeed_rpm = 1000.0\ninitial_load_nm = 0.0\nload_nm = 2.0\n'
                    f"load_step_s = {STEP_S}\nsettle_s = 0.1\nduration_s = 0.15\n", encoding="utf-8")
    cfg = RunConfig.from_options({**options, "scenario": str(path)})
    res = run_closed_loop(cfg)
    assert res.metrics["end_reason"] == "completed"
    periods = res.outcome.periods.all()
    return periods["t"], periods["omega_m"]


def _spectrum(t: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(frequency [Hz], magnitude) of the speed in the 80 ms after the load step: the slow recovery taken out by a
    cubic fit, a Hann window, zero-padded to 0.6 Hz bins."""
    sel = (t >= STEP_S + 0.5e-3) & (t < STEP_S + 0.08)
    tt, ww = t[sel] - t[sel][0], w[sel]
    ww = ww - np.polyval(np.polyfit(tt, ww, 3), tt)
    n = 1 << 14
    return np.fft.rfftfreq(n, TS), np.abs(np.fft.rfft(ww * np.hanning(len(ww)), n))


def _resonance_hz(t: np.ndarray, w: np.ndarray) -> float:
    """The frequency [Hz] of the largest spectral peak above 100 Hz (below: the speed loop's recovery), refined by
    a parabola through the log magnitudes of its bin and the two beside it."""
    freqs, spectrum = _spectrum(t, w)
    spectrum[freqs < 100.0] = 0.0
    k = int(np.argmax(spectrum))
    a, b, c = np.log(spectrum[k - 1 : k + 2])
    return float(freqs[k] + 0.5 * (a - c) / (a - 2 * b + c) * (freqs[1] - freqs[0]))


def _band_peak(t: np.ndarray, w: np.ndarray, f_hz: float) -> float:
    """The largest spectral magnitude within ±10 % of `f_hz`."""
    freqs, spectrum = _spectrum(t, w)
    return float(np.max(spectrum[(freqs > 0.9 * f_hz) & (freqs < 1.1 * f_hz)]))


def test_a_closed_loop_run_shows_the_torsional_resonance(tmp_path: Path) -> None:
    """J_l = J_m/10 on a shaft tuned to 300 Hz, lightly damped, under the motor's own speed PI (its proportional
    torque damps the mode a little: measured 0.1 % off). The one-mass run of J_m + J_l has no peak there."""
    j_load = 0.1 * J_MOTOR
    f_want = 300.0
    k = (2 * math.pi * f_want) ** 2 * J_MOTOR * j_load / (J_MOTOR + j_load)
    options = _options(shaft="two-mass", load_inertia=j_load, shaft_stiffness=k, shaft_damping=1e-4)
    mech = build_plant(RunConfig.from_options(options)).mechanics
    assert isinstance(mech, TwoMassMechanics)
    assert mech.resonance_rad_s / (2 * math.pi) == pytest.approx(f_want, rel=1e-9)
    t, w = _speeds(options, tmp_path)
    assert _resonance_hz(t, w) == pytest.approx(f_want, rel=0.03)
    t1, w1 = _speeds(_options(set={"j": J_MOTOR + j_load}), tmp_path)
    assert _band_peak(t, w, f_want) > 5.0 * _band_peak(t1, w1, f_want)  # measured: 20×


def test_a_stiff_shaft_runs_as_one_mass_of_the_summed_inertia(tmp_path: Path) -> None:
    """k = 1e8 N·m/rad (resonance ~ 100 kHz, far above the loop) between J1 and J2 = J1: the closed-loop speed
    follows the one-mass run with J1 + J2 through the load step."""
    t2, w2 = _speeds(_options(shaft="two-mass", load_inertia=J_MOTOR, shaft_stiffness=1e8, shaft_damping=50.0),
                     tmp_path)
    t1, w1 = _speeds(_options(set={"j": 2 * J_MOTOR}), tmp_path)
    assert np.array_equal(t1, t2)
    dip = float(np.max(w1[t1 < STEP_S]) - np.min(w1))
    assert dip > 1.0  # the load step moved the speed
    assert float(np.max(np.abs(w2 - w1))) < 1e-3 * dip  # measured: 4e-5
    assert abs(float(np.mean(w2[t2 > STEP_S])) - float(np.mean(w1[t1 > STEP_S]))) < 1e-4 * dip
    _, w0 = _speeds(_options(), tmp_path)  # the motor's mass alone: the comparison tells the inertias apart
    assert float(np.max(np.abs(w0 - w1))) > 0.1 * dip  # measured: 0.28


def test_the_shaft_options_reach_the_plant() -> None:
    cfg = RunConfig.from_options(_options(shaft="two-mass", load_inertia=2e-3, shaft_stiffness=500.0,
                                          shaft_damping=0.01))
    mech = build_plant(cfg).mechanics
    assert isinstance(mech, TwoMassMechanics)
    assert (mech.j_motor, mech.j_load, mech.k_shaft, mech.c_shaft) == (J_MOTOR, 2e-3, 500.0, 0.01)
    assert cfg.scenario.driven_inertia_kgm2(J_MOTOR) == pytest.approx(J_MOTOR + 2e-3)
    rigid = RunConfig.from_options(_options())
    assert not isinstance(build_plant(rigid).mechanics, TwoMassMechanics)


@pytest.mark.parametrize(("extra", "named"), [
    ({"shaft": "two-mass", "shaft_stiffness": 500.0}, "load_inertia_kgm2"),
    ({"shaft": "two-mass", "load_inertia": 1e-3}, "shaft_stiffness_nm_per_rad"),
    ({"shaft": "two-mass", "load_inertia": -1e-3, "shaft_stiffness": 500.0}, "--load-inertia"),
    ({"shaft": "two-mass", "load_inertia": 1e-3, "shaft_stiffness": 0.0}, "--shaft-stiffness"),
    ({"shaft": "two-mass", "load_inertia": 1e-3, "shaft_stiffness": 5.0, "shaft_damping": -1.0}, "--shaft-damping"),
    ({"shaft": "elastic"}, "--shaft"),
    ({"shaft_stiffness": 500.0}, "--shaft-stiffness"),
    ({"shaft": "two-mass", "load_inertia": 1e-3, "shaft_stiffness": 5.0, "scenario": "dyno-steady"}, "dyno"),
])
def test_bad_shaft_values_are_refused_naming_the_field(extra: dict[str, Any], named: str) -> None:
    with pytest.raises(ParameterError, match=named) as err:
        RunConfig.from_options(_options(**extra))
    assert "\n" not in str(err.value)


def test_a_sweep_grid_varies_the_shaft() -> None:
    from pmsm_hil.app.sweep.configure import base_options, build_runs

    base = base_options({"shaft": "two-mass", "load_inertia": 1e-3, "no_log": True})
    runs = build_runs(base, [(("shaft_stiffness", "200"),), (("shaft_stiffness", "800"),)], 1)
    assert [r.cfg.scenario.shaft_stiffness_nm_per_rad for r in runs] == [200.0, 800.0]
    with pytest.raises(ParameterError, match="--grid shaft_stiffness"):
        build_runs(base, [(("shaft_stiffness", "-1"),)], 1)


def test_a_scenario_file_sets_the_shaft(tmp_path: Path) -> None:
    path = tmp_path / "shaft.toml"
    path.write_text('shaft = "two-mass"\nload_inertia_kgm2 = 2e-3\nshaft_stiffness_nm_per_rad = 800.0\n',
                    encoding="utf-8")
    sc = load_scenario(str(path))
    assert (sc.shaft, sc.load_inertia_kgm2, sc.shaft_stiffness_nm_per_rad, sc.shaft_damping_nms_per_rad) == (
        "two-mass", 2e-3, 800.0, 0.0)


@pytest.mark.parametrize(("text", "named"), [
    ('shaft = "two-mass"\nload_inertia_kgm2 = 2e-3\n', "shaft_stiffness_nm_per_rad"),
    ("shaft = 2\n", "'shaft' must be a string"),
])
def test_a_bad_shaft_in_a_scenario_file_is_named(text: str, named: str, tmp_path: Path) -> None:
    path = tmp_path / "shaft.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(InputFileError, match=named):
        load_scenario(str(path))
