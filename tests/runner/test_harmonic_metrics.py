"""The harmonic metrics of real closed-loop runs against an independent FFT of the logged currents, for each
machine kind: the PMSM, the dual three-phase PMSM and the induction machine (whose stator
runs at p·ω_m + ω_slip). A speed step in the window: no THD number, the reason instead."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.app.cli.report_table import format_metrics
from pmsm_hil.hil.motor_params import parse_set_options
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runlog.reader import read_trace
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario


def _peak_hz(t: np.ndarray, x: np.ndarray) -> float:
    """The frequency [Hz] of x(t)'s largest spectral line: a Hann-windowed FFT of x resampled at 2 µs, the peak
    bin refined by parabolic interpolation of the log magnitude."""
    y = np.interp(np.arange(t[0], t[-1], 2e-6), t, x)
    spec = np.abs(np.fft.rfft((y - y.mean()) * np.hanning(y.shape[0])))
    k0 = int(np.argmax(spec[2:])) + 2
    a, b, c = np.log(spec[k0 - 1: k0 + 2])
    return float((k0 + 0.5 * (a - c) / (a - 2.0 * b + c)) / (y.shape[0] * 2e-6))


def _independent(t: np.ndarray, x: np.ndarray) -> tuple[float, float, float]:
    """(frequency [Hz], fundamental amplitude [A], THD_total [%]) of x(t) without the metrics' code: the frequency
    of the spectrum's peak (`_peak_hz`), x resampled at 2 µs over the whole periods of it that fit, a plain FFT
    (the fundamental on bin M), THD_total from Parseval: sqrt(RMS² − DC² − A1²/2) / (A1/√2)."""
    f = _peak_hz(t, x)
    periods = math.floor((t[-1] - t[0]) * f)
    n = round(periods / f / 2e-6)
    y = np.interp(t[0] + np.arange(n) * (periods / f / n), t, x)
    a1 = 2.0 * abs(np.fft.rfft(y)[periods]) / n
    ac_ms = float(np.mean(y * y)) - float(np.mean(y)) ** 2
    return f, a1, 100.0 * math.sqrt(max(ac_ms - a1 * a1 / 2.0, 0.0)) / (a1 / math.sqrt(2.0))


#: controller parameters of the dual three-phase preset (src/pmsm_hil/app/compare/presets/zhang2021-speed-step.toml: the
#: speed PI for its J = 0.1 kg·m²; the default gains suit the niu2020 machine and overshoot into a trip here)
ZHANG_PARAMS = {"torque_band": 4.0, "speed_kp": 3.0, "speed_ki": 5.0}


def _run(tmp_path: Path, motor: str, controller: str, sets: tuple[str, ...] = (), **scenario: float) -> tuple[
        dict, np.ndarray, float]:
    sc = load_scenario(str(scenario.pop("name", "steady"))).with_overrides(**scenario)
    cfg = RunConfig(motor=load_motor(motor, parse_set_options(list(sets))), scenario=sc, controller=controller,
                    controller_params=ZHANG_PARAMS if motor.startswith("zhang2021") else {},
                    out_dir=tmp_path / "run", log_trace=True)
    res = run_closed_loop(cfg)
    assert res.metrics["end_code"] == 0, res.metrics["end_reason"]
    assert res.mcap_path is not None
    trace = read_trace(res.mcap_path)
    return res.metrics, trace[trace["t"] >= sc.settle_s], sc.settle_s


@pytest.mark.parametrize(("motor", "controller", "scenario"), [
    ("niu2020-ipmsm", "mpcc", {}),
    ("zhang2021-dtpmsm", "mptc2", {"speed_rpm": 1500.0, "load_nm": 40.0}),  # mptc1 trips (overcurrent) here
    ("im-2k2", "im-foc", {"speed_rpm": 1000.0, "load_nm": 10.0}),
])
def test_the_fundamental_and_thd_match_an_independent_fft(tmp_path: Path, motor: str, controller: str,
                                                          scenario: dict[str, float]) -> None:
    m, trace, _ = _run(tmp_path, motor, controller, **scenario)
    f, amp, thd_total = _independent(trace["t"], trace["i_a"])
    assert m["not_applicable"] == {}
    assert m["current_fundamental_a"] == pytest.approx(amp, rel=0.01)
    assert m["current_fundamental_hz"] == pytest.approx(f, rel=0.005)
    assert abs(m["current_thd_total_pct"] - thd_total) <= 0.5
    assert m["current_thd_pct"] <= m["current_thd_total_pct"]


def test_the_induction_machine_fundamental_is_the_stator_frequency(tmp_path: Path) -> None:
    """The IM's stator runs faster than p·ω_m (motoring: slip > 0); the metrics take the stator's."""
    m, trace, _ = _run(tmp_path, "im-2k2", "im-foc", speed_rpm=1000.0, load_nm=10.0)
    f_peak = _peak_hz(trace["t"], trace["i_a"])
    assert m["current_fundamental_hz"] > m["current_rotor_electrical_hz"] * 1.005
    assert m["current_fundamental_hz"] == pytest.approx(f_peak, rel=0.01)


def test_a_speed_step_in_the_window_prints_no_thd_number(tmp_path: Path) -> None:
    m, _, _ = _run(tmp_path, "niu2020-ipmsm", "mpcc", name="speed-step")
    assert m["current_thd_pct"] is None and m["current_thd_total_pct"] is None
    assert "changes by" in m["not_applicable"]["current_thd_pct"]
    table = format_metrics(m)
    thd_lines = [ln for ln in table.splitlines() if "THD" in ln and "not applicable:" not in ln]
    assert thd_lines and all("n/a (not applicable)" in ln for ln in thd_lines)
    assert "not applicable: current_thd_pct" in table
