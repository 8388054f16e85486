"""The niu2020-readings preset (fcs_reading variants) and explicit operating points in compare presets."""

from __future__ import annotations

from pathlib import Path

from pmsm_hil.app.compare import load_preset
from tests.compare._presets import assert_rejected, run_text

HEAD = 'name = "x"\nmotor = "niu2020-ipmsm"\nscenario = "steady"\ncontrollers = ["fcs-mpc-2"]\n'


def test_readings_preset_points_and_variants() -> None:
    p = load_preset("niu2020-readings")
    assert p.points[0] == {"speed_rpm": 1500.0, "load_nm": 7.0} and len(p.points) == 5
    specs = {v.label: v for v in p.specs()}
    assert specs["I rot11 band 1 (43)"].params == {"fcs_reading": 43.0, "torque_band": 1.0}
    assert specs["II (0) as built"].controller == "fcs-mpc-2" and specs["II (0) as built"].params == {}
    # fcs-mpc-1's default is reading 11, so its built reading 0 is sent explicitly; fcs-mpc-2's default is 0
    assert specs["I (0) as built"].params == {"fcs_reading": 0.0}
    assert all(f"({int(v.params.get('fcs_reading', 0))})" in v.label for v in p.variants)
    assert all("fcs_reading" in v.params for v in p.variants if v.controller == "fcs-mpc-1")


def test_bad_points_name_the_key(tmp_path: Path) -> None:
    for body, match in (("points = []\n", "points"), ("points = [{ rpm = 1.0 }]\n", r"points\[0\]"),
                        ('points = [{ load_nm = "x" }]\n', "load_nm"),
                        ('points = [{ load_nm = 1.0 }]\nsweep = { key = "load_nm", values = [1.0] }\n', "not both")):
        assert_rejected(tmp_path, HEAD + body, match)


def test_points_run_once_each(tmp_path: Path) -> None:
    res = run_text(tmp_path, HEAD + "settle_s = 0.02\nduration_s = 0.02\n"
                   "points = [{ speed_rpm = 1500.0, load_nm = 7.0 }, { speed_rpm = 750.0, load_nm = 3.5 }]\n")
    assert [(r["speed_rpm"], r["load_nm"]) for r in res.rows] == [(1500.0, 7.0), (750.0, 3.5)]
    assert all(r["end_reason"] == "completed" and r["candidate_miss_rate"] is not None for r in res.rows)
