"""`--adc-delay`: the Measurement is the plant sampled at the firmware's ADC instant inside the period (loop.c
sample_adc), from the period's own gate sequence; the records keep the period-start samples."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.mechanics import DynoMechanics
from pmsm_hil.hil.plant import Plant
from pmsm_hil.hil.presets_loader import load_pmsm
from pmsm_hil.hil.pwm import SINGLE, duty_sequence
from pmsm_hil.hil.runlog.reader import read_frames, read_periods
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.protocol.codec import decode_frame
from pmsm_hil.protocol.codec_duty import duty_raw
from pmsm_hil.protocol.frame import Frame

TS = 100e-6
LSB_A = 0.01  # Measurement current resolution (hil.dbc)


def _run(out: Path, delay_s: float) -> tuple[np.ndarray, list[dict[str, float]]]:
    """foc (duty cycles, single update) on the dyno at 1000 rpm / 4 N·m: records and decoded Measurements by k."""
    scenario = load_scenario("dyno-steady").with_overrides(settle_s=0.0, duration_s=0.01)
    cfg = RunConfig(motor=load_pmsm("niu2020-ipmsm"), scenario=scenario, controller="foc", ts_s=TS,
                    adc_delay_s=delay_s, out_dir=out)
    assert run_closed_loop(cfg).metrics["end_code"] == 0
    periods = read_periods(out / "run.mcap")
    meas: list[dict[str, float]] = []
    for f in read_frames(out / "run.mcap"):
        frame = Frame(int(f["arbitration_id"]), bytes(f["data"][: f["length"]]), bool(f["is_fd"]))
        if f["direction"] == 0 and frame.arbitration_id == 0x108:  # MeasFd
            meas.append(decode_frame(frame)[1])
    return periods, meas


def _truncated(states: tuple[int, ...], durs: tuple[int, ...], delay_ns: int) -> tuple[list[int], list[int]]:
    """The first `delay_ns` of a period's gate sequence."""
    out_s, out_d, left = [], [], delay_ns
    for s, d in zip(states, durs, strict=True):
        if left <= 0:
            break
        out_s.append(s)
        out_d.append(min(d, left))
        left -= min(d, left)
    return out_s, out_d


def test_the_measurement_is_the_plant_at_the_adc_instant(tmp_path: Path) -> None:
    delay_ns = 30_000  # inside the active vectors of the centre-aligned pattern: the ripple shows
    periods, meas = _run(tmp_path / "d", delay_ns * 1e-9)
    motor = load_pmsm("niu2020-ipmsm")
    checked = differs = 0
    for k in range(2, len(periods) - 1):
        rec = periods[k]
        assert int(rec["n_duties"]) == 3
        # the plant from the period start the records hold, through the first delay_ns of period k's sequence
        # (a plant whose period is the delay: the Python plant checks that a sequence fills its period)
        plant = Plant(motor, delay_ns * 1e-9, DynoMechanics(float(rec["omega_m"]) * 30.0 / math.pi), trace_dt_s=None)
        plant.set_state(i_d=float(rec["i_d"]), i_q=float(rec["i_q"]), theta_e=float(rec["theta_e"]),
                        omega_m=float(rec["omega_m"]), gate=0)  # single update: every period ends in V0
        states, durs = duty_sequence([duty_raw(float(d)) for d in rec["duties"][:3]], round(TS * 1e9), SINGLE)
        plant.advance(*_truncated(states, durs, delay_ns))
        smp = plant.sample()
        for phase in ("i_a", "i_b", "i_c"):
            assert abs(meas[k][phase] - getattr(smp, phase)) <= 0.5 * LSB_A + 1e-9, (k, phase)
            differs += abs(meas[k][phase] - float(rec[phase])) > 2 * LSB_A  # not the period-start sample
        checked += 1
    assert checked > 90 and differs > checked  # the ripple between the valley and the ADC instant is visible


def test_no_delay_samples_at_the_period_start(tmp_path: Path) -> None:
    periods, meas = _run(tmp_path / "z", 0.0)
    for k in range(len(periods)):
        for phase in ("i_a", "i_b", "i_c"):
            assert abs(meas[k][phase] - float(periods[k][phase])) <= 0.5 * LSB_A + 1e-9


def test_the_delay_must_fall_inside_the_period() -> None:
    scenario = load_scenario("steady")
    with pytest.raises(ParameterError, match="--adc-delay must be shorter than the control period"):
        RunConfig(motor=load_pmsm("niu2020-ipmsm"), scenario=scenario, adc_delay_s=TS)
    with pytest.raises(ParameterError, match="--adc-delay must be ≥ 0"):
        RunConfig(motor=load_pmsm("niu2020-ipmsm"), scenario=scenario, adc_delay_s=-1e-6)
