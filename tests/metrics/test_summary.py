"""compute_run_metrics: the CLI contract keys, values on a synthetic run, degenerate inputs."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.metrics import MetricsError, MetricsWindowError, compute_run_metrics
from pmsm_hil.hil.metrics.streaming import HOLD_TORQUE
from tests.metrics._signals import make_periods, make_trace, three_phase

TS = 100e-6
OMEGA = 1000.0 * 2 * math.pi / 60.0  # 1000 rpm
P = 4
F1 = P * OMEGA / (2 * math.pi)
LINK = {"frames_tx": 10, "frames_rx": 9, "crc_errors": 1, "lost": 0, "late": 2}

CONTRACT_KEYS = {
    "periods",
    "sim_time_s",
    "wall_time_s",
    "loop_rate_hz",
    "torque_mean_nm",
    "torque_ripple_rms_nm",
    "torque_ripple_pp_nm",
    "speed_mean_rpm",
    "current_thd_pct",
    "current_thd_total_pct",
    "current_fundamental_a",
    "switching_freq_khz",
    "switching_freq_intra_khz",
    "exec_time_us",
    "exec_split_us",
    "candidates_evaluated_mean",
    "narrow_pulses",
    "deadline_misses",
    "link",
    "torque_error_mean_nm",
}


def _run(omega: float = OMEGA, duration: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    tr = make_trace(duration, 2e-6, omega)
    tr["i_a"], tr["i_b"], tr["i_c"] = three_phase(tr["t"], F1 if omega else 0.0, {1: 8.0, 5: 0.4, 7: 0.24})
    tr["torque"] = 4.0 + 0.3 * np.sin(2 * np.pi * 2000.0 * tr["t"])
    n = round(duration / TS)
    p = make_periods(n, TS)
    p["leg_transitions"] = 4
    p["boundary_transitions"] = 2
    p["narrow_pulses"][::10] = 1
    p["exec_time_ns"] = 20_000
    p["exec_split_ns"] = np.array([1000, 2000, 17000])
    p["candidates"] = 7
    p["load_torque"] = 3.9
    return p, tr


def test_metrics_on_synthetic_run() -> None:
    p, tr = _run()
    m = compute_run_metrics(p, tr, ts_s=TS, pole_pairs=P, wall_time_s=0.5, link_stats=LINK, deadline_misses=3)
    assert m.keys() >= CONTRACT_KEYS
    json.dumps(m)  # JSON-serialisable for the CLI
    assert m["periods"] == 2000 and m["sim_time_s"] == pytest.approx(0.2)
    assert m["loop_rate_hz"] == pytest.approx(4000.0)
    assert m["torque_mean_nm"] == pytest.approx(4.0, abs=1e-6)
    assert m["torque_ripple_rms_nm"] == pytest.approx(0.3 / math.sqrt(2), rel=1e-4)
    assert m["torque_ripple_pp_nm"] == pytest.approx(0.6, rel=1e-4)
    assert m["torque_error_mean_nm"] == pytest.approx(0.1, abs=1e-6)
    assert m["torque_error_reference"] == HOLD_TORQUE
    assert m["speed_mean_rpm"] == pytest.approx(1000.0)
    assert m["current_fundamental_a"] == pytest.approx(8.0, abs=1e-3)
    expected = 100 * math.hypot(0.4, 0.24) / 8.0
    assert abs(m["current_thd_pct"] - expected) < 0.1
    assert abs(m["current_thd_total_pct"] - expected) < 0.1
    for phase in ("a", "b", "c"):
        assert abs(m["current_thd_phases_pct"][phase]["harmonics"] - expected) < 0.1
    assert m["switching_freq_khz"] == pytest.approx(6.6667, abs=1e-3)
    assert m["switching_freq_intra_khz"] == pytest.approx(3.3333, abs=1e-3)
    assert m["exec_time_us"] == {"median": 20.0, "p99": 20.0, "max": 20.0}
    assert m["exec_split_us"] == {"measure": 1.0, "reference": 2.0, "predict": 17.0}
    assert m["candidates_evaluated_mean"] == 7.0
    assert m["narrow_pulses"] == 200
    assert m["deadline_misses"] == 3
    assert m["link"] == LINK


def test_torque_error_is_against_the_hold_torque_whatever_the_firmware_reports() -> None:
    """One definition for every target: the firmware's debug `torque_ref` (SIL, in process) or its absence (NaN:
    QEMU, boards) gives the same figure, against T_load + B·ω_ref + J·dω_ref/dt from the host's records."""
    p, tr = _run()
    p["speed_ref"] = OMEGA
    args: dict[str, Any] = {"ts_s": TS, "pole_pairs": P, "wall_time_s": 1.0, "link_stats": {}, "deadline_misses": 0,
                            "friction_nms": 1e-3, "inertia_kgm2": 0.01}
    without = compute_run_metrics(p, tr, **args)
    p["torque_ref"] = 4.5  # a firmware that reports its speed PI's output
    with_ref = compute_run_metrics(p, tr, **args)
    assert with_ref["torque_error_mean_nm"] == without["torque_error_mean_nm"]
    assert without["torque_error_mean_nm"] == pytest.approx(4.0 - (3.9 + 1e-3 * OMEGA), abs=1e-6)
    assert without["torque_error_reference"] == with_ref["torque_error_reference"] == HOLD_TORQUE
    assert without["link"] == dict.fromkeys(LINK, 0)
    p["speed_ref"] = np.linspace(0.0, OMEGA, p.shape[0])  # a ramp: J·dω_ref/dt to deliver too
    ramp = compute_run_metrics(p, tr, **args)
    accel = OMEGA / (p.shape[0] * TS)
    assert ramp["torque_error_mean_nm"] == pytest.approx(4.0 - (3.9 + 1e-3 * OMEGA / 2 + 0.01 * accel), abs=1e-6)


def test_zero_speed_reports_null_thd_with_reason() -> None:
    p, tr = _run(omega=0.0)
    m = compute_run_metrics(p, tr, ts_s=TS, pole_pairs=P, wall_time_s=0.0, link_stats={}, deadline_misses=0)
    assert m["current_thd_pct"] is None and m["current_thd_total_pct"] is None
    assert "stator frequency ~ 0" in m["current_thd_note"]
    assert m["not_applicable"]["current_thd_pct"] == m["current_thd_note"]
    assert m["loop_rate_hz"] is None


def test_window_shorter_than_one_electrical_period_is_reported() -> None:
    p, tr = _run(duration=0.01)  # 0.67 of an electrical period at 66.7 Hz
    m = compute_run_metrics(p, tr, ts_s=TS, pole_pairs=P, wall_time_s=1.0, link_stats={}, deadline_misses=0)
    assert m["current_thd_pct"] is None
    assert (
        "trace.i_a" in m["current_thd_note"] and "shorter than one electrical period" in m["current_thd_note"]
    )


def test_empty_window_is_a_clear_error() -> None:
    p, tr = _run()
    with pytest.raises(MetricsWindowError, match="periods"):
        compute_run_metrics(
            p[:0], tr, ts_s=TS, pole_pairs=P, wall_time_s=1.0, link_stats={}, deadline_misses=0
        )
    with pytest.raises(MetricsWindowError, match="trace"):
        compute_run_metrics(
            p, tr[:0], ts_s=TS, pole_pairs=P, wall_time_s=1.0, link_stats={}, deadline_misses=0
        )


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"ts_s": 0.0}, "ts_s"),
        ({"pole_pairs": 0}, "pole_pairs"),
        ({"wall_time_s": -1.0}, "wall_time_s"),
        ({"deadline_misses": -1}, "deadline_misses"),
        ({"link_stats": {"lost": "x"}}, "link_stats"),
    ],
)
def test_bad_arguments_name_the_field(kwargs: dict[str, object], field: str) -> None:
    p, tr = _run(duration=0.05)
    args: dict[str, Any] = {
        "ts_s": TS,
        "pole_pairs": P,
        "wall_time_s": 1.0,
        "link_stats": {},
        "deadline_misses": 0,
    }
    args.update(kwargs)
    with pytest.raises(MetricsError, match=field):
        compute_run_metrics(p, tr, **args)


def test_missing_field_is_named() -> None:
    p, tr = _run(duration=0.05)
    with pytest.raises(MetricsError, match="torque"):
        compute_run_metrics(
            p, tr[["t", "i_a"]], ts_s=TS, pole_pairs=P, wall_time_s=1.0, link_stats={}, deadline_misses=0
        )
