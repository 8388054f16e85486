"""The scheduler that skips the quiet models (Board.SKIP_QUIET: the TIM1/ADC event group while its earliest event
is ahead and none of it was accessed, encoder timers until accessed): the models it skips. That it gives the
reference scheduler's records bit for bit (every model asked at every step) is checked with the board's other fast
paths in tests/board/test_native_exc.py."""

from __future__ import annotations

from typing import Any

import pytest

from pmsm_hil.sim_target.stm32g4.board import Board
from tests.board.test_native_exc import EXAMPLE_BOARD, example


def test_an_encoder_timer_rests_and_the_group_is_skipped(monkeypatch: pytest.MonkeyPatch) -> None:
    """The example's TIM3 counts encoder edges: it rests (not asked at every step), and the TIM1/ADC group is asked
    only when its event is due or it was accessed, not at every step."""
    from pmsm_hil.sim_target.stm32g4.board_file import load_board
    from pmsm_hil.sim_target.stm32g4.link import BoardLink

    monkeypatch.setattr(Board, "SKIP_QUIET", True)
    monkeypatch.setattr(Board, "NATIVE_CORE", False)
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


def test_the_c_scheduler_skips_the_same_models(monkeypatch: pytest.MonkeyPatch) -> None:
    """The scheduler in C (Board.NATIVE_CORE) keeps the skipping: TIM3 rests, and the group's Python models are
    called (in the batch of the Python models due) at fewer steps than FDCAN1, which is asked at every step without
    the event-driven caching (Board.EVENT_DRIVEN, tests/board/test_event_driven.py); TIM3 only when the call starts
    and after an access (the group's Python references: the models in C are called by the C core without
    Python)."""
    from pmsm_hil.sim_target.stm32g4 import periph_native
    from pmsm_hil.sim_target.stm32g4.board_file import load_board
    from pmsm_hil.sim_target.stm32g4.link import BoardLink

    monkeypatch.setattr(Board, "NATIVE_CORE", True)
    monkeypatch.setattr(Board, "EVENT_DRIVEN", False)
    monkeypatch.setattr(periph_native, "NATIVE", False)
    link = BoardLink(example(), load_board(EXAMPLE_BOARD), ts_s=50e-6, pole_pairs=4)
    board = link.board
    assert board._native_core
    tim3 = board.peripherals["TIM3"]
    assert board._core.models[board._slot[tim3]].resting
    calls = {"TIM1": 0, "FDCAN1": 0, "TIM3": 0}
    for name in calls:
        model = board.peripherals[name]
        advance = model.advance

        def counted(now: int, name: str = name, advance: Any = advance) -> None:
            calls[name] += 1
            advance(now)

        monkeypatch.setattr(model, "advance", counted)
    board.run_until(board.now + 20 * link.period_cycles)
    assert 0 < calls["TIM1"] < calls["FDCAN1"]
    assert calls["TIM3"] < calls["FDCAN1"]  # asked when the call starts and after the firmware read it


def test_a_model_in_c_reports_its_own_register_accesses(monkeypatch: pytest.MonkeyPatch) -> None:
    """A model in C serves its registers itself, so it reports an access through its irq sink's `touched`
    (c/periph_ops.h): a group member's access makes the scheduler ask the group again, and a store that moves the
    model's next event before the running slice's end stops the core at its next block, as Board._touch and
    Board._store do for the Python models."""
    import ctypes

    from pmsm_hil.sim_target.stm32g4.board_file import load_board
    from pmsm_hil.sim_target.stm32g4.core_native import trampoline_ops
    from pmsm_hil.sim_target.stm32g4.link import BoardLink
    from pmsm_hil.sim_target.stm32g4.peripherals.base import REGISTRY
    from pmsm_hil.sim_target.stm32g4.peripherals.tim1_native import NativeTim1

    monkeypatch.setattr(Board, "NATIVE_CORE", True)
    for cls in (REGISTRY["TIM1"], NativeTim1):  # a trampoline: the state pointer below is a stand-in
        monkeypatch.setattr(cls, "native_ops", property(
            lambda self: trampoline_ops(self, self.bus.cpu.hook_failed)), raising=False)
    link = BoardLink(example(), load_board(EXAMPLE_BOARD), ts_s=50e-6, pole_pairs=4)
    board = link.board
    core, tim1 = board._core, board.peripherals["TIM1"]
    slot = core.models[board._slot[tim1]]
    assert not slot.python and slot.in_group
    slot.ops.self = 0x1234  # the model's own state pointer, as a model in C has
    sink = board.irq_sink
    touched = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_int)(sink.touched)
    core.group_touched = 0
    counter = board.cpu.counter
    counter.limit = 1 << 62
    touched(sink.board, 0x1234, 0)  # a read: the group is asked again, the slice runs on
    assert core.group_touched == 1 and counter.limit == 1 << 62
    touched(sink.board, 0x1234, 1)  # a store: TIM1's next event is before the slice's end
    assert tim1.next_event(board.now) is not None and counter.limit == counter.count
    core.group_touched = 0
    touched(sink.board, 0x9999, 1)  # no model of the board: nothing
    assert core.group_touched == 0
