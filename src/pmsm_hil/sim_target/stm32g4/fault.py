"""A fault of the firmware on the virtual board, reported as the `qemu:` target reports one (the fault, pc and lr
with the function and offset, CFSR and HFSR decoded, BFAR/MMFAR when valid): the board stops at the faulting
instruction instead of running the firmware's own fault handler, so the report names the instruction itself."""

from __future__ import annotations

import contextlib
from pathlib import Path

from pmsm_hil.sim_target.elf import ElfError, elf_function_at
from pmsm_hil.sim_target.qemu import CFSR_BITS, FAULT_NAMES, HFSR_BITS
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError

#: CFSR bits the board sets (Armv7-M B3.2.15)
IBUSERR, PRECISERR, BFARVALID = 1 << 8, 1 << 9, 1 << 15
UNDEFINSTR, INVSTATE, INVPC, NOCP, UNALIGNED, DIVBYZERO = 1 << 16, 1 << 17, 1 << 18, 1 << 19, 1 << 24, 1 << 25
FORCED = 1 << 30


def _bits(value: int, names: dict[int, str]) -> str:
    found = [name for bit, name in names.items() if value >> bit & 1]
    return f" ({' '.join(found)})" if found else ""


def where(elf: str | Path | None, address: int) -> str:
    """`0x08000123 (function+0x1c)`, the function named from the ELF's symbols when one holds the address."""
    name = None
    if elf is not None:
        with contextlib.suppress(ElfError, OSError):
            name = elf_function_at(elf, address)
    return f"{address:#010x}" + (f" ({name})" if name else "")


class BoardFaultError(BoardError):
    """The firmware faulted on the virtual board (a safety stop, exit 3, as a `qemu:` target's fault)."""

    def __init__(self, exc: int, pc: int, lr: int, cfsr: int, hfsr: int, bfar: int, mmfar: int,
                 elf: str | Path | None, detail: str = "") -> None:
        self.exc, self.pc, self.lr, self.cfsr, self.hfsr = exc, pc, lr, cfsr, hfsr
        text = (f"{FAULT_NAMES.get(exc, f'fault exception {exc}')} at pc {where(elf, pc)}, lr {where(elf, lr)}, "
                f"CFSR {cfsr:#010x}{_bits(cfsr, CFSR_BITS)}, HFSR {hfsr:#010x}{_bits(hfsr, HFSR_BITS)}")
        if cfsr & BFARVALID:
            text += f", BFAR {bfar:#010x}"
        if cfsr & (1 << 7):
            text += f", MMFAR {mmfar:#010x}"
        if detail:
            text += f" ({detail})"
        self.description = text
        super().__init__(text)
