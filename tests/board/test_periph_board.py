"""DMA, CORDIC and the watchdogs on the whole virtual board (the Cortex-M4F core running a firmware): needs the
board (`stm32g4.board`), its `BusMaster.access` and a part listing DMA1, DMAMUX1, CORDIC, WWDG and IWDG."""

from __future__ import annotations

import struct
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from pmsm_hil.sim_target.stm32g4.peripherals.iwdg import LSI_HZ
from pmsm_hil.sim_target.stm32g4.peripherals.watchdog import WatchdogResetError

board_module: Any = pytest.importorskip("pmsm_hil.sim_target.stm32g4.board")
part_module: Any = pytest.importorskip("pmsm_hil.sim_target.stm32g4.part")
RESET_HZ = 16_000_000  # HSI16: the firmware leaves the clock at its reset value


def u32(board: Any, name: str) -> int:
    address = board.symbol(name)
    assert address is not None, name
    return int(struct.unpack("<I", board.read_memory(address, 4))[0])


def test_dma_cordic_and_the_window_watchdog_reset(build_fw: Callable[..., Path]) -> None:
    board = board_module.Board(part_module.PARTS["stm32g474"], build_fw("periph"))
    with pytest.raises(WatchdogResetError, match="watchdog reset by WWDG") as ended:
        board.run_until(RESET_HZ // 4)
    assert u32(board, "dma_ok") == 1
    assert u32(board, "cordic_sin") / 2 ** 31 == pytest.approx(0.5, abs=2 ** -22)
    assert u32(board, "cordic_cos") / 2 ** 31 == pytest.approx(3 ** 0.5 / 2, abs=2 ** -22)
    # the early wakeup interrupt ran once, at counter 0x40; the reset came one tick (4096 * 8 cycles) later
    assert u32(board, "ewi_count") == 1 and u32(board, "wwdg_cr") == 0xC0
    assert ended.value.cycle == pytest.approx(64 * 4096 * 8, abs=2000)


def test_the_independent_watchdog_reset(build_fw: Callable[..., Path]) -> None:
    board = board_module.Board(part_module.PARTS["stm32g474"], build_fw("periph", "USE_IWDG"))
    with pytest.raises(WatchdogResetError, match="watchdog reset by IWDG") as ended:
        board.run_until(RESET_HZ // 4)
    assert u32(board, "iwdg_sr_polls") > 0  # the update flags held for a few LSI periods
    tick = RESET_HZ * 4 // LSI_HZ
    assert ended.value.cycle == pytest.approx(100 * tick + 6 * RESET_HZ // LSI_HZ, rel=0.05)


def test_the_bus_master_path_reaches_memory_and_registers_as_the_cpu_does(build_fw: Callable[..., Path]) -> None:
    board = board_module.Board(part_module.PARTS["stm32g474"], build_fw("periph"))
    sram = 0x2000_4000
    assert board.access(sram, 4, 0x1234_5678, now=0) == 0x1234_5678
    assert board.access(sram, 2, now=0) == 0x5678 and board.read_memory(sram, 4) == bytes.fromhex("78563412")
    assert board.access(0x0800_0004, 4, now=0) == board.cpu.read_u32(4)  # the reset vector, through flash
    with pytest.raises(board_module.BoardError, match="flash is read-only"):
        board.access(0x0800_0000, 4, 0, now=0)
    with pytest.raises(board_module.BoardError, match="private peripheral bus"):
        board.access(0xE000_E100, 4, now=0)
    with pytest.raises(board_module.BoardError, match=r"0x40010200 \(SYSCFG.*not modelled"):
        board.access(0x4001_0200, 4, now=0)
    with pytest.raises(board_module.BoardError, match="no memory"):
        board.access(0x2002_0000, 4, now=0)
    # a register write has the model's effects, and a timed model's new event stops the running slice
    tim1 = board.peripherals["TIM1"]
    board.cpu.counter.limit = 1 << 40
    board.access(tim1.base + 0x2C, 4, 999, now=0)  # ARR
    board.access(tim1.base + 0x00, 4, 1, now=0)  # CR1.CEN
    assert board.access(tim1.base + 0x2C, 4, now=0) == 999 and tim1.running
    assert board.cpu.counter.limit == board.cpu.counter.count
