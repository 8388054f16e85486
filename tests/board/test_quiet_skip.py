"""The scheduler that skips the quiet models (Board.SKIP_QUIET: the TIM1/ADC event group while its earliest event
is ahead and none of it was accessed, encoder timers until accessed) against the reference that asks every model at
every step: the same records, bit for bit — every Command's frame, the handler, sleep and entry counts per period,
each exception's handler times and latencies, the ADC samples, the core's registers and SRAM at the end — for the
example firmware (examples/stm32g4_foc, its LATE_ISR and FAULT variants) and the test firmwares."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from pmsm_hil.sim_target.stm32g4.board import Board
from tests.board.test_native_exc import EXAMPLE_BOARD, PERIODS, example, records


def run(elf: Path, board_file: str | Path | None, skip: bool, monkeypatch: pytest.MonkeyPatch,
        periods: int = PERIODS) -> dict[str, Any]:
    monkeypatch.setattr(Board, "SKIP_QUIET", skip)
    out = records(elf, board_file, True, monkeypatch, periods)
    return out


def same(elf: Path, board_file: str | Path | None, monkeypatch: pytest.MonkeyPatch,
         periods: int = PERIODS) -> dict[str, Any]:
    every = run(elf, board_file, False, monkeypatch, periods)
    skipping = run(elf, board_file, True, monkeypatch, periods)
    for key in every:
        assert skipping[key] == every[key], f"{key} differs between the skipping and the reference scheduler"
    return skipping


@pytest.mark.parametrize("defines", [(), ("LATE_ISR",)], ids=["example", "late_isr"])
def test_the_example_firmware_gives_the_same_records(defines: tuple[str, ...],
                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    out = same(example(*defines), EXAMPLE_BOARD, monkeypatch)
    assert len(out["frames"]) >= PERIODS and sum(out["entries"]) >= PERIODS and not out["error"]


def test_the_example_fault_variant_gives_the_same_fault_report(monkeypatch: pytest.MonkeyPatch) -> None:
    out = same(example("FAULT"), EXAMPLE_BOARD, monkeypatch, 2100)  # its current loop faults in ISR 2000
    assert "CFSR" in out["error"] and len(out["isr"]) < 2100


@pytest.mark.parametrize(("name", "defines"), [("foc_bench", ()), ("pwm_adc", ("LATE",)),
                                                ("pwm_adc", ("FAULT_AT=40",))])
def test_the_test_firmwares_give_the_same_records(name: str, defines: tuple[str, ...],
                                                  build_fw: Callable[..., Path],
                                                  monkeypatch: pytest.MonkeyPatch) -> None:
    out = same(build_fw(name, *defines), None, monkeypatch)
    assert sum(out["entries"]) > 0


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
