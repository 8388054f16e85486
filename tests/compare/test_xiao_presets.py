"""Compare presets of the Xiao paper: variants with controller parameters, rotor-angle spread, eq. (12)."""

from __future__ import annotations

from pathlib import Path

import pytest

from pmsm_hil.app.compare import load_preset
from pmsm_hil.app.compare.runs import evaluation_e
from pmsm_hil.app.compare.spread import aggregate
from tests.compare._presets import assert_rejected, run_text


def test_tthr_sweep_preset_has_both_zero_rules() -> None:
    p = load_preset("xiao2023-tthr-sweep")
    specs = {v.label: v for v in p.specs()}
    assert specs["t_thr=15us"].params == {"t_thr": 15e-6}
    assert specs["t_thr=8us min_tr"].params == {"t_thr": 8e-6, "zero_select": 1.0}
    assert p.evaluation == (6.0, 6.67) and len(p.theta0_rad) == 4
    steady = load_preset("xiao2023-steady")
    assert steady.equal_fav == ("hv-mpfc", "3vmpc") and steady.equal_fav_metric == "switching_freq_intra_khz"


def test_evaluation_function_matches_table4_row() -> None:
    row = {"torque_ripple_pp_nm": 0.76, "switching_freq_khz": 6.67, "current_thd_pct": 4.61}
    assert evaluation_e(row, 6.0, 6.67) == pytest.approx(1.17, abs=0.005)
    assert evaluation_e({**row, "current_thd_pct": None}, 6.0, 6.67) is None


def test_aggregate_mean_and_spread() -> None:
    rows = [{"group": "main", "label": "a", "controller": "x", "ts_us": 100.0, "speed_rpm": 1.0, "load_nm": 2.0,
             "torque_ripple_rms_nm": v, "end_reason": "completed"} for v in (1.0, 3.0)]
    agg = aggregate(rows)
    assert len(agg) == 1 and agg[0]["n_runs"] == 2
    assert (agg[0]["torque_ripple_rms_nm"], agg[0]["torque_ripple_rms_nm_min"], agg[0]["torque_ripple_rms_nm_max"]) \
        == (2.0, 1.0, 3.0)


def test_bad_variant_and_param_name_the_key(tmp_path: Path) -> None:
    head = 'name = "x"\nmotor = "xiao2023-spmsm"\nscenario = "steady"\n'
    assert_rejected(tmp_path, head + '[[variants]]\nlabel = "a"\ncontroller = "hv-mpfc"\n'
                    'params = { zero_select = "lots" }\n', "zero_select")
    assert_rejected(tmp_path, head + 'controllers = ["3vmpc"]\nparams = { nope = 1.0 }\n', "nope")
    assert_rejected(tmp_path, head + 'controllers = ["3vmpc"]\ntheta0_rad = []\n', "theta0_rad")


def test_short_variant_run_spreads_over_rotor_angles(tmp_path: Path) -> None:
    res = run_text(
        tmp_path,
        'name = "short"\nmotor = "xiao2023-spmsm"\nscenario = "steady"\nspeed_rpm = 1000.0\nload_nm = 4.0\n'
        'settle_s = 0.03\nduration_s = 0.03\ntheta0_rad = [0.0, 1.0]\n'
        'evaluation = { torque_base_nm = 6.0, fav_base_khz = 6.67 }\n'
        '[[variants]]\nlabel = "hv 15"\ncontroller = "hv-mpfc"\nparams = { t_thr = 15e-6 }\n')
    assert [r["theta0_rad"] for r in res.rows] == [0.0, 1.0]
    assert all(r["label"] == "hv 15" and r["end_reason"] == "completed" for r in res.rows)
    assert all(r["narrow_pulses"] == 0 for r in res.rows)  # T_THR 15 µs > T_lim = 8 µs
    assert all(r["eval_e"] is not None and r["eval_e_intra"] < r["eval_e"] for r in res.rows)
