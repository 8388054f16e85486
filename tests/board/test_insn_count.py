"""The instruction counter's table of decoded flash blocks (c/insn_count.c): a block's count is kept by address and
size, and forgotten when the flash is written (the same block then counts its new instructions)."""

from __future__ import annotations

import pytest

from pmsm_hil.sim_target.stm32g4.cpu import Cpu
from pmsm_hil.sim_target.stm32g4.part import FLASH_BASE, PARTS

#: movs r0, #1; movs r1, #2; b . : a 6-byte block of three instructions, then the branch's own block
THREE = bytes.fromhex("0120" "0221" "fee7")
#: mov.w r0, #1; b . : the same 6 bytes as two instructions
TWO = bytes.fromhex("4ff00100" "fee7")


@pytest.mark.parametrize("cache", [True, False], ids=["cached", "decoded"])
def test_a_rewritten_flash_block_counts_its_new_instructions(cache: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(Cpu, "COUNT_CACHE", cache)
    cpu = Cpu(PARTS["stm32g474"])
    for code, n in ((THREE, 3), (THREE, 3), (TWO, 2)):
        cpu.load(FLASH_BASE, code)
        cpu.counter.count = 0
        assert cpu.run(FLASH_BASE, 1).kind == "limit"  # the first block runs whole, the branch's is not begun
        assert cpu.counter.count == n
        assert cpu.pc == FLASH_BASE + 4
    assert cpu.counter.unknown_blocks == 0
