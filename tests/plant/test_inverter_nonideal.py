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
    ideal = _plant()
    ideal.set_state(i_d=2.0)
    ideal.advance([0, 4], [50_000, 50_000])
    deadtime = _plant(t_dead=2.5e-6)
    deadtime.set_state(i_d=2.0)
    deadtime.advance([0, 4], [50_000, 50_000])
    shifted = _plant()
    shifted.set_state(i_d=2.0)
    shifted.advance([0, 4], [52_500, 47_500])
    assert deadtime.sample().i_d == pytest.approx(shifted.sample().i_d, abs=1e-9)
    assert deadtime.sample().i_d != pytest.approx(ideal.sample().i_d, abs=1e-6)


def test_dead_time_does_not_delay_falling_edge_for_positive_current() -> None:
    ideal = _plant()
    ideal.set_state(i_d=2.0)
    ideal.advance([4, 0], [50_000, 50_000])
    deadtime = _plant(t_dead=2.5e-6)
    deadtime.set_state(i_d=2.0)
    deadtime.advance([4, 0], [50_000, 50_000])
    # the first edge (0→1 at t = 0) is delayed, the falling edge is not
    shifted = _plant()
    shifted.set_state(i_d=2.0)
    shifted.advance([0, 4, 0], [2_500, 47_500, 50_000])
    assert deadtime.sample().i_d == pytest.approx(shifted.sample().i_d, abs=1e-9)


@pytest.mark.parametrize(
    ("states", "durations", "field"),
    [([8], [TS_NS], "code 8"), ([1], [TS_NS - 1], "sum to 99999 ns"), ([1, 2], [-5, TS_NS + 5], "negative"),
     ([], [], "1..8 states")],
)
def test_bad_sequences_raise_clear_errors(states: list[int], durations: list[int], field: str) -> None:
    with pytest.raises(SequenceError, match=field):
        _plant().advance(states, durations)
