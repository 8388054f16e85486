"""The SRAMs mapped without execute permission until the core first fetches from them (Cpu.LAZY_RAM_EXEC): a
firmware that runs code from SRAM (and is interrupted there) runs exactly as with the SRAMs executable from the
start, with the C scheduler and with the Python one."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from unicorn import arm_const as arm

from pmsm_hil.sim_target.stm32g4.board import Board
from pmsm_hil.sim_target.stm32g4.cpu import Cpu
from pmsm_hil.sim_target.stm32g4.part import PARTS

HCLK = 170_000_000
REGS = (arm.UC_ARM_REG_R0, arm.UC_ARM_REG_SP, arm.UC_ARM_REG_LR, arm.UC_ARM_REG_PC, arm.UC_ARM_REG_XPSR)


def run(elf: Path, lazy: bool, native_core: bool, monkeypatch: pytest.MonkeyPatch) -> dict[str, Any]:
    monkeypatch.setattr(Cpu, "LAZY_RAM_EXEC", lazy)
    monkeypatch.setattr(Board, "NATIVE_CORE", native_core)
    board = Board(PARTS["stm32g474"], elf)
    assert board._native_core == native_core
    assert board.cpu.ram_exec.value == (0 if lazy else 1)
    board.run_until(HCLK // 20)
    assert board.cpu.ram_exec.value == 1  # the firmware ran code from SRAM
    return {"now": board.now, "count": board.cpu.counter.count, "regs": [board.cpu.reg(r) for r in REGS],
            "isr": {e: (s.entries, s.cycles, s.latency) for e, s in board.isr.items()},
            "sram": board.read_memory(0x2000_0000, board.part.sram_size)}


@pytest.mark.parametrize("native_core", [True, False], ids=["c_core", "python_core"])
def test_code_run_from_sram_gives_the_same_run(native_core: bool, build_fw: Callable[..., Path],
                                               monkeypatch: pytest.MonkeyPatch) -> None:
    elf = build_fw("core", "RAM_CODE")
    board = Board(PARTS["stm32g474"], elf)
    address = board.symbol("ram_twice")
    assert address is not None and 0x2000_0000 <= address < 0x2002_0000  # the function is in SRAM
    lazy, reference = (run(elf, lazy, native_core, monkeypatch) for lazy in (True, False))
    for key in reference:
        assert lazy[key] == reference[key], key
    sum_at = board.symbol("ram_sum")
    assert sum_at is not None
    assert int.from_bytes(lazy["sram"][sum_at - 0x2000_0000:][:4], "little") == (99999 * 100000) & 0xFFFF_FFFF
    assert lazy["isr"][15][0] > 0  # SysTick interrupted the firmware
