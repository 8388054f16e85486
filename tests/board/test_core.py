"""The virtual board's core: clock set-up, SysTick rate, NVIC nesting and tail-chaining with the FP context
kept, DWT CYCCNT, the USART2 console, the fault report and the error of an unmodelled access."""

from __future__ import annotations

import struct
from collections.abc import Callable
from pathlib import Path

import pytest

from pmsm_hil.sim_target.stm32g4.board import Board
from pmsm_hil.sim_target.stm32g4.fault import BoardFaultError
from pmsm_hil.sim_target.stm32g4.part import PARTS
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError

HCLK = 170_000_000


def u32(board: Board, name: str, index: int = 0) -> int:
    address = board.symbol(name)
    assert address is not None, name
    return int(struct.unpack("<I", board.read_memory(address + 4 * index, 4))[0])


@pytest.fixture(scope="module")
def core_run(build_fw: Callable[..., Path]) -> Board:
    lines: list[str] = []
    board = Board(PARTS["stm32g474"], build_fw("core"), console=lambda source, line: lines.append(line))
    board.run_until(HCLK // 20)  # 50 ms at 170 MHz
    board.lines = lines  # type: ignore[attr-defined]
    return board


def test_clock_reaches_170_mhz_from_hse_through_the_pll(core_run: Board) -> None:
    assert u32(core_run, "sysclk_ok") == 1
    assert core_run.hclk_hz == HCLK


def test_systick_runs_at_1_khz_of_the_core_clock(core_run: Board) -> None:
    ticks = u32(core_run, "ticks")
    # 50 ms, minus the start-up at 16 MHz before SysTick is set (a few thousand cycles): 49 or 50 ticks
    assert ticks in (49, 50)
    assert core_run.isr[15].entries == ticks


def test_nested_and_tail_chained_interrupts_by_priority(core_run: Board) -> None:
    # IRQ0 (0x80) pends IRQ1 (0x40: preempts at once) and IRQ2 (0xC0: runs after IRQ0 returns, tail-chained)
    assert u32(core_run, "n_order") == 4
    assert [u32(core_run, "order", i) for i in range(4)] == [0, 1, 10, 2]


def test_fp_context_survives_fp_using_handlers(core_run: Board) -> None:
    assert u32(core_run, "done") == 1
    assert u32(core_run, "fp_errors") == 0


def test_dwt_cyccnt_counts_core_cycles(core_run: Board) -> None:
    elapsed = u32(core_run, "cyc_b") - u32(core_run, "cyc_a")
    assert 300 < elapsed < 2000  # 100 turns of an empty volatile loop


def test_usart2_lines_reach_the_console(core_run: Board) -> None:
    assert core_run.lines == ["board core test"]  # type: ignore[attr-defined]


def test_a_read_of_nothing_is_a_fault_report_naming_the_function(build_fw: Callable[..., Path]) -> None:
    board = Board(PARTS["stm32g474"], build_fw("errors", "FAULT_READ"))
    with pytest.raises(BoardFaultError) as info:
        board.run_until(1_000_000)
    text = str(info.value)
    assert text.startswith("HardFault at pc 0x080")
    assert "(touch_nothing+0x" in text
    assert "PRECISERR" in text and "BFARVALID" in text and "BFAR 0x9f000000" in text
    assert "\n" not in text


def test_an_unmodelled_peripheral_is_one_line_naming_address_and_function(build_fw: Callable[..., Path]) -> None:
    board = Board(PARTS["stm32g474"], build_fw("errors", "UNMODELLED"))
    with pytest.raises(BoardError) as info:
        board.run_until(1_000_000)
    text = str(info.value)
    assert "write of 0x40010200 (SYSCFG/VREFBUF/COMP/OPAMP, not modelled by the virtual board)" in text
    assert "touch_comp" in text
    assert "\n" not in text


def test_an_unmodelled_register_of_a_modelled_peripheral_names_it_and_the_function(
        build_fw: Callable[..., Path]) -> None:
    board = Board(PARTS["stm32g474"], build_fw("errors", "UNMODELLED_REGISTER"))
    with pytest.raises(BoardError) as info:
        board.run_until(1_000_000)
    text = str(info.value)
    assert text.startswith("write of TIM1 register at offset 0x070 (0x40012c70), which the virtual board does not "
                           "model, at pc 0x080")
    assert "touch_tim1_reserved" in text and "\n" not in text


def test_a_corrupt_exc_return_is_a_fault(build_fw: Callable[..., Path]) -> None:
    board = Board(PARTS["stm32g474"], build_fw("errors", "BAD_RETURN"))
    with pytest.raises(BoardFaultError, match="INVPC"):
        board.run_until(1_000_000)


def test_the_g431_runs_the_same_firmware_in_its_smaller_memories(build_fw: Callable[..., Path]) -> None:
    board = Board(PARTS["stm32g431"], build_fw("core", part="g431"))
    board.run_until(HCLK // 100)  # 10 ms
    assert u32(board, "ticks") in (9, 10)
    assert u32(board, "fp_errors") == 0
    assert board.scs.dbgmcu_read(0, 4, 0) == 0x1000_6468


@pytest.mark.parametrize("part", ["stm32g474", "stm32g431"])
def test_ccm_sram_is_aliased_after_sram(build_fw: Callable[..., Path], part: str) -> None:
    board = Board(PARTS[part], build_fw("core", part=part[-4:]))
    board.write_memory(0x1000_0000 + 16, b"\x12\x34\x56\x78")
    assert board.read_memory(PARTS[part].ccm_alias + 16, 4) == b"\x12\x34\x56\x78"
    board.write_memory(PARTS[part].ccm_alias + 32, b"\xaa")
    assert board.read_memory(0x1000_0000 + 32, 1) == b"\xaa"
