"""Dead time and minimum pulse width in the inverter model."""

from __future__ import annotations

import pytest

from pmsm_hil.hil.errors import SequenceError
from pmsm_hil.hil.mechanics import DynoMechanics
from pmsm_hil.hil.plant import Plant
from pmsm_hil.hil.presets_loader import load_motor

TS_NS = 100_000


def _plant(t_dead: float = 0.0, t_mpw: float = 0.0) -> Plant:
    params = load_motor("xiao2023-spmsm", {"t_dead": t_dead, "t_mpw": t_mpw})
    return Plant(params, 1e-4, DynoMechanics(0.0), trace_dt_s=None)


def _i_d_after(states: list[int], durations_ns: list[int], i_d: float, gate: int | None = None,
              t_dead: float = 0.0) -> float:
    """i_d [A] at the end of one period of `states` for `durations_ns`, from i_d and `gate` at standstill."""
    plant = _plant(t_dead=t_dead)
    plant.set_state(i_d=i_d, gate=gate)
    plant.advance(states, durations_ns)
    return plant.sample().i_d


def test_pulse_shorter_than_tmpw_never_reaches_the_gate() -> None:
    with_pulse = _plant(t_mpw=3e-6)
    stats = with_pulse.advance([0, 4, 0], [49_000, 2_000, 49_000])
    without = _plant(t_mpw=3e-6)
    without.advance([0], [TS_NS])
    assert stats.suppressed_pulses == 1
    assert stats.leg_transitions == 0
    assert with_pulse.sample().i_d == without.sample().i_d == 0.0


def test_pulse_longer_than_tmpw_is_applied_and_counted_as_narrow_below_tlim() -> None:
    plant = _plant(t_dead=2.5e-6, t_mpw=3e-6)  # T_lim = 8 µs
    stats = plant.advance([0, 4, 0], [45_000, 5_000, 50_000])
    assert stats.suppressed_pulses == 0
    assert stats.leg_transitions == 2
    assert stats.narrow_pulses == 1
    assert plant.sample().i_d != 0.0


def test_dead_time_delays_rising_edge_for_positive_current() -> None:
    """Current out of leg a (i_a > 0): during dead time the lower diode clamps a to the low rail,
    so a 0→1 command edge takes effect t_dead later: equal to an ideal pulse shortened by t_dead."""
    deadtime = _i_d_after([0, 4], [50_000, 50_000], 2.0, t_dead=2.5e-6)
    assert deadtime == pytest.approx(_i_d_after([0, 4], [52_500, 47_500], 2.0), abs=1e-9)
    assert deadtime != pytest.approx(_i_d_after([0, 4], [50_000, 50_000], 2.0), abs=1e-6)


def test_dead_time_does_not_delay_falling_edge_for_positive_current() -> None:
    deadtime = _i_d_after([4, 0], [50_000, 50_000], 2.0, t_dead=2.5e-6)
    # the first edge (0→1 at t = 0) is delayed, the falling edge is not
    assert deadtime == pytest.approx(_i_d_after([0, 4, 0], [2_500, 47_500, 50_000], 2.0), abs=1e-9)


@pytest.mark.parametrize(
    ("states", "durations", "field"),
    [([8], [TS_NS], "code 8"), ([1], [TS_NS - 1], "sum to 99999 ns"), ([1, 2], [-5, TS_NS + 5], "negative"),
     ([], [], "1..16 states")],
)
def test_bad_sequences_raise_clear_errors(states: list[int], durations: list[int], field: str) -> None:
    with pytest.raises(SequenceError, match=field):
        _plant().advance(states, durations)


def test_dead_time_delays_falling_edge_for_negative_current() -> None:
    """Current into leg a (i_a < 0): the upper diode holds a at +Vdc for t_dead after a 1→0 command:
    the pulse is widened by t_dead (hand calculation: +Vdc·t_dead volt-seconds on leg a)."""
    deadtime = _i_d_after([4, 0], [40_000, 60_000], -3.0, gate=4, t_dead=2.5e-6)
    assert deadtime == pytest.approx(_i_d_after([4, 0], [42_500, 57_500], -3.0, gate=4), abs=1e-9)


def test_current_reaching_zero_in_dead_time_leaves_the_phase_open() -> None:
    """i_a < 0 and leg a commanded 1→0: the upper diode conducts, +Vdc drives i_a up to zero within the
    dead time; then the diode blocks and phase a stays open (i_a = 0, i_b = −i_c) until t_dead ends."""
    params = load_motor("xiao2023-spmsm", {"t_dead": 2.5e-6, "t_mpw": 0.0})
    plant = Plant(params, 1e-4, DynoMechanics(0.0), trace_dt_s=0.25e-6)
    plant.set_state(i_d=-0.27, i_q=0.2, gate=4)  # i_b ≠ i_c: a loop current b→c remains when a opens
    stats = plant.advance([4, 0], [10_000, 90_000])
    tr = plant.last_trace
    assert stats.open_phase_events == 1
    t = tr[:, 0]
    open_rows = tr[(t >= 11.75e-6) & (t < 12.5e-6)]
    assert len(open_rows) >= 3
    assert abs(open_rows[:, 1]).max() < 1e-9  # i_a held at zero, no chattering
    assert abs(open_rows[:, 2] + open_rows[:, 3]).max() < 1e-9
    assert abs(open_rows[:, 2]).min() > 0.1
    before = tr[(t >= 10.0e-6) & (t < 10.5e-6)]
    assert (before[:, 1] < 0).all()
    # leg a low after the dead time with b, c low: zero vector at standstill, i_a stays at zero
    after = tr[(t > 13e-6) & (t < 20e-6)]
    assert abs(after[:, 1]).max() < 1e-9


def test_uncompensated_dead_time_costs_voltage_seconds_with_the_sign_of_the_current() -> None:
    """Average leg-a voltage error over many PWM periods ≈ −sign(i_a)·Vdc·t_dead/Ts (hand calculation)."""
    out: dict[str, float] = {}
    for label, t_dead in (("ideal", 0.0), ("dead", 2.5e-6)):
        plant = _plant(t_dead=t_dead)
        plant.set_state(i_d=5.0)  # large positive i_a: never reaches zero in 2.5 µs
        for _ in range(3):
            plant.advance([0, 4, 0], [25_000, 50_000, 25_000])
        out[label] = plant.sample().i_d
    # leg a high 50 µs per period in the ideal case, 47.5 µs with dead time (rising edges delayed)
    assert out["dead"] < out["ideal"]


def test_gated_narrow_pulses_exclude_suppressed_ones() -> None:
    plant = _plant(t_dead=2.5e-6, t_mpw=3e-6)  # T_lim = 8 µs
    stats = plant.advance([0, 4, 0, 4, 0], [20_000, 2_000, 30_000, 5_000, 43_000])
    assert stats.narrow_pulses == 2  # the 2 µs and the 5 µs pulse were requested
    assert stats.suppressed_pulses == 1  # the 2 µs one never reaches the gate
    assert stats.narrow_pulses_gated == 1
