"""Plant accuracy against a tight-tolerance scipy solution of the same equations."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.mechanics import DynoMechanics
from pmsm_hil.hil.plant import Plant
from pmsm_hil.hil.presets_loader import load_motor
from tests.plant.reference_solver import rows_and_references, solve_period

TS = 100e-6
TS_NS = 100_000


def _run_against_reference(sequences: list[tuple[list[int], list[int]]], motor: str = "niu2020-ipmsm",
                           rpm: float = 1500.0) -> float:
    params = load_motor(motor, {"t_dead": 0.0, "t_mpw": 0.0})  # the reference has ideal switches
    plant = Plant(params, TS, DynoMechanics(rpm), trace_dt_s=None)
    i_dq = (0.0, 0.0)
    theta = 0.0
    omega = rpm * 2 * math.pi / 60
    worst = 0.0
    for states, durs in sequences:
        plant.advance(states, durs)
        i_d, i_q, theta = solve_period(params, omega, theta, i_dq, states, [d * 1e-9 for d in durs])
        smp = plant.sample()
        worst = max(worst, abs(smp.i_d - i_d), abs(smp.i_q - i_q))
        # the reference carries its own state forward (independent of the plant)
        i_dq = (i_d, i_q)
    return worst


def test_single_vector_periods_match_reference_within_1mA() -> None:
    rng = np.random.default_rng(20201)
    seqs = [([int(s)], [TS_NS]) for s in rng.integers(0, 8, 2000)]
    worst = _run_against_reference(seqs)
    assert worst <= 1e-3, f"max |Δi| = {worst:.3e} A"


def test_three_vector_sequences_match_reference_within_1mA() -> None:
    rng = np.random.default_rng(7)
    seqs = []
    for _ in range(2000):
        cuts = np.sort(rng.integers(0, TS_NS + 1, 2))
        durs = [int(cuts[0]), int(cuts[1] - cuts[0]), int(TS_NS - cuts[1])]
        seqs.append(([int(s) for s in rng.integers(0, 8, 3)], durs))
    worst = _run_against_reference(seqs)
    assert worst <= 1e-3, f"max |Δi| = {worst:.3e} A"


def test_spmsm_preset_matches_reference() -> None:
    rng = np.random.default_rng(3)
    seqs = [([int(s)], [TS_NS]) for s in rng.integers(0, 8, 300)]
    worst = _run_against_reference(seqs, motor="xiao2023-spmsm", rpm=2000.0)
    assert worst <= 1e-3


def test_trace_matches_period_end_state_and_is_dense() -> None:
    params = load_motor("niu2020-ipmsm")
    plant = Plant(params, TS, DynoMechanics(1500.0), trace_dt_s=2e-6)
    plant.advance([4], [TS_NS])
    tr = plant.last_trace.copy()
    assert tr.shape[0] == 50
    assert np.allclose(np.diff(tr[:, 0]), 2e-6)
    # the next period's first trace row is the exact state at the period boundary
    end = plant.sample()
    plant.advance([4], [TS_NS])
    first = plant.last_trace[0]
    assert first[0] == pytest.approx(1e-4)
    assert first[1] == pytest.approx(end.i_a, abs=1e-12)
    assert first[4] == pytest.approx(end.torque, abs=1e-12)


def test_zero_voltage_at_standstill_keeps_zero_current() -> None:
    plant = Plant(load_motor("niu2020-ipmsm"), TS, DynoMechanics(0.0))
    for _ in range(10):
        plant.advance([0], [TS_NS])
    smp = plant.sample()
    assert smp.i_d == 0.0 and smp.i_q == 0.0


def test_steady_state_with_long_zero_vector_is_short_circuit_current() -> None:
    """Zero vector at speed: currents settle to the analytic short-circuit point."""
    params = load_motor("xiao2023-spmsm")
    plant = Plant(params, TS, DynoMechanics(1000.0), trace_dt_s=None)
    for _ in range(3000):
        plant.advance([0], [TS_NS])
    w = params.pole_pairs * 1000 * 2 * math.pi / 60
    # R id − w L iq = 0 ; R iq + w L id + w ψ = 0
    den = params.rs**2 + (w * params.ld) ** 2
    id_ss = -(w * params.ld) * w * params.psi_f / den
    iq_ss = -params.rs * w * params.psi_f / den
    smp = plant.sample()
    assert smp.i_d == pytest.approx(id_ss, abs=1e-6)
    assert smp.i_q == pytest.approx(iq_ss, abs=1e-6)


def test_period_peak_current_is_the_largest_traced_phase_current() -> None:
    plant = Plant(load_motor("niu2020-ipmsm"), TS, DynoMechanics(1500.0), trace_dt_s=2e-6)
    peaks = []
    for state in (4, 6, 2, 3, 1, 5, 0):
        st = plant.advance([state], [TS_NS])
        tr = plant.last_trace
        peaks.append(st.peak_current_a)
        assert st.peak_current_a == pytest.approx(np.abs(tr[:, 1:4]).max())
    assert max(peaks) > 1.0


@pytest.mark.parametrize(("motor", "trace_dt_ns"), [("niu2020-ipmsm", 2000), ("niu2020-ipmsm", 700),
                                                     ("xiao2023-spmsm", 2000)])
def test_trace_rows_equal_the_closed_form_at_their_times(motor: str, trace_dt_ns: int) -> None:
    """Trace rows come from addition theorems stepped along the row grid (restarted every 32 rows); each row
    equals the closed-form state at its time, computed by a second plant whose period ends exactly there."""
    params = load_motor(motor)
    traced = Plant(params, TS, DynoMechanics(1500.0), trace_dt_s=trace_dt_ns * 1e-9)
    for st in (6, 2, 3, 4, 4):
        traced.advance([st], [TS_NS])
    start = traced.sample()
    traced.advance([4], [TS_NS])  # same vector as before: no gate edge inside the period
    rows = traced.last_trace.copy()
    assert rows.shape[0] == -(-TS_NS // trace_dt_ns)

    def reference(offset_ns: int) -> Any:
        ref_plant = Plant(params, offset_ns * 1e-9, DynoMechanics(1500.0), trace_dt_s=None)
        ref_plant.set_state(i_d=start.i_d, i_q=start.i_q, theta_e=start.theta_e, gate=4)
        ref_plant.advance([4], [offset_ns])
        return ref_plant.sample()

    checked, worst = 0, 0.0
    for row, ref in rows_and_references(rows, start.t, reference):
        worst = max(worst, abs(row[1] - ref.i_a), abs(row[2] - ref.i_b), abs(row[3] - ref.i_c))
        assert row[4] == pytest.approx(ref.torque, rel=1e-12, abs=1e-12)
        checked += 1
    assert checked >= rows.shape[0] - 2
    assert worst < 1e-11  # A, against currents of ~10 A: rounding only
