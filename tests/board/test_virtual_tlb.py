"""Unicorn's virtual TLB with the board's fill (Cpu.VIRTUAL_TLB, c/insn_count.c hil_counter_tlb_fill) against the
CPU's own fill: a branch to each region of the Armv7-M memory map (flash, SRAM, CCM-SRAM, an MMIO page, unmapped
and execute-never addresses, the exception-return range) stops the core the same way at the same pc after the same
count. The firmware runs compare both in tests/board/test_native_exc.py (FAST_PATHS)."""

from __future__ import annotations

import pytest

from pmsm_hil.sim_target.stm32g4.cpu import Cpu, Stop
from pmsm_hil.sim_target.stm32g4.part import FLASH_BASE, PARTS

TARGETS = (0x0800_0101, 0x2000_8001, 0x1000_0001, 0x4002_1001, 0x4003_1001, 0x5FFF_FF01, 0x3FFF_FF01, 0x6000_0001,
           0xA000_0001, 0xDFFF_FF01, 0xE000_0001, 0xFFFF_EF01, 0xFFFF_FB01, 0xFFFF_FFF9)


def branch_to(target: int, virtual: bool, monkeypatch: pytest.MonkeyPatch) -> tuple[Stop, int, int]:
    monkeypatch.setattr(Cpu, "VIRTUAL_TLB", virtual)
    cpu = Cpu(PARTS["stm32g474"])
    cpu.map_mmio(0x4002_1000, 0x1000, lambda _a, _n: 0xBF00_BF00, lambda _a, _n, _v: None)
    # movs r0, #1; ldr r1, [pc, #4]; bx r1; nop; .word target
    cpu.load(FLASH_BASE, bytes.fromhex("0120" "0149" "0847" "00bf") + target.to_bytes(4, "little"))
    cpu.load(FLASH_BASE + 0x100, bytes.fromhex("fee7"))  # b .
    stop = cpu.run(FLASH_BASE, 200)
    return stop, cpu.pc, cpu.counter.count


@pytest.mark.parametrize("target", TARGETS, ids=hex)
def test_a_branch_anywhere_stops_as_with_the_cpus_tlb(target: int, monkeypatch: pytest.MonkeyPatch) -> None:
    assert branch_to(target, True, monkeypatch) == branch_to(target, False, monkeypatch)


def test_an_execute_never_fetch_is_the_prefetch_abort(monkeypatch: pytest.MonkeyPatch) -> None:
    stop, pc, _ = branch_to(0x4002_1001, True, monkeypatch)
    assert (stop.kind, stop.intno, pc) == ("interrupt", 3, 0x4002_1000)
