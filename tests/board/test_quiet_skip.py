"""The scheduler that skips the quiet models (Board.SKIP_QUIET: the TIM1/ADC event group while its earliest event
is ahead and none of it was accessed, encoder timers until accessed): the models it skips. That it gives the
reference scheduler's records bit for bit (every model asked at every step) is checked with the board's other fast
paths in tests/board/test_native_exc.py."""

from __future__ import annotations

import pytest

from pmsm_hil.sim_target.stm32g4.board import Board
from tests.board.test_native_exc import EXAMPLE_BOARD, example


def test_an_encoder_timer_rests_and_the_group_is_skipped(monkeypatch: pytest.MonkeyPatch) -> None:
    """The example's TIM3 counts encoder edges: it rests (not asked at every step), and the TIM1/ADC group is asked
    only when its event is due or it was accessed, not at every step."""
    from pmsm_hil.sim_target.stm32g4.board_file import load_board
    from pmsm_hil.sim_target.stm32g4.link import BoardLink

    monkeypatch.setattr(Board, "SKIP_QUIET", True)
    link = BoardLink(example(), load_board(EXAMPLE_BOARD), ts_s=50e-6, pole_pairs=4)
    board = link.board
    assert board.peripherals["TIM3"] in board._resting
    tim1 = board.peripherals["TIM1"]
    calls = {"tim1": 0}
    advance = tim1.advance

    def counted(now: int) -> None:
        calls["tim1"] += 1
        advance(now)

    monkeypatch.setattr(tim1, "advance", counted)
    steps = {"n": 0}
    systick_advance = board.scs.systick.advance

    def step(now: int) -> None:
        steps["n"] += 1
        systick_advance(now)

    monkeypatch.setattr(board.scs.systick, "advance", step)
    board.run_until(board.now + 20 * link.period_cycles)
    assert 0 < calls["tim1"] < steps["n"]
