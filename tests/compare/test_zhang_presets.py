"""zhang2021 compare presets: they load, and a run ended by the plant's protection becomes a row."""

from __future__ import annotations

from pathlib import Path

from pmsm_hil.app.compare import load_preset
from pmsm_hil.app.compare.spread import aggregate
from pmsm_hil.app.compare.table import format_table
from tests.compare._presets import run_text


def test_zhang_presets_load() -> None:
    names = ("steady", "speed-step", "thd-vs-load", "ripple-vs-speed")
    presets = {n: load_preset(f"zhang2021-{n}") for n in names}
    for p in presets.values():
        assert p.motor == "zhang2021-dtpmsm"
        assert p.controllers == ("mptc1", "mptc2", "mptc3")
        assert p.params["torque_band"] == 4.0
    assert presets["steady"].speed_rpm == 1500.0 and presets["steady"].load_nm == 40.0
    assert len(presets["steady"].theta0_rad) == 4
    assert presets["thd-vs-load"].sweep_values[0] == 8.0 and presets["thd-vs-load"].sweep_values[-1] == 80.0
    assert presets["ripple-vs-speed"].load_nm == 98.0
    assert presets["steady"].paper["mptc1"]["current_thd_pct"] == 15.44


def test_trip_is_a_row_and_six_phase_metrics_reach_the_table(tmp_path: Path) -> None:
    res = run_text(tmp_path, 'name = "z"\nmotor = "zhang2021-dtpmsm"\nscenario = "steady"\n'
                   'controllers = ["mptc1", "mptc2"]\nspeed_rpm = 1500.0\nload_nm = 40.0\n'
                   'settle_s = 0.01\nduration_s = 0.02\n')
    trip, ok = res.rows
    assert "plant trip" in trip["end_reason"] and trip["xy_current_rms_a"] is None
    assert ok["end_reason"] == "completed" and ok["xy_current_rms_a"] > 0.0
    assert ok["current_distortion_rms_a"] > 0.0
    agg = {r["label"]: r for r in aggregate(res.rows)}
    assert agg["mptc1"]["n_trips"] == 1 and agg["mptc2"]["n_trips"] == 0
    lines = format_table(res)
    assert "x-y rms A" in "\n".join(lines) and "trips" in "\n".join(lines)
    assert max(len(line) for line in lines) <= 120
