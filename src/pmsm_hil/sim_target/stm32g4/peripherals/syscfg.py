"""SYSCFG (RM0440 chapter 10): MEMRMP, CFGR1, SCSR, CFGR2, SWPR, SKR as storage at their reset values, and the
EXTICR1-4 port selection of the GPIO EXTI lines 0-15 (4 bits per line: 0 port A ... 6 port G), which EXTI
follows (a change re-samples the line's level so that the switch itself is no edge)."""

from __future__ import annotations

from typing import ClassVar, Protocol

from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError, register
from pmsm_hil.sim_target.stm32g4.peripherals.regs import RegisterFile

MEMRMP, CFGR1, EXTICR1, SCSR, CFGR2, SWPR, SKR = 0x00, 0x04, 0x08, 0x18, 0x1C, 0x20, 0x24
PORTS = "ABCDEFG"


class _LineSampler(Protocol):
    def advance(self, now: int) -> None: ...

    def resample(self, now: int) -> None: ...


@register("SYSCFG")
class Syscfg(RegisterFile):
    base = 0x4001_0000
    size = 0x30
    RESET: ClassVar[dict[int, int]] = {MEMRMP: 0, CFGR1: 0x7C00_0001, 0x08: 0, 0x0C: 0, 0x10: 0, 0x14: 0, SCSR: 0,
                                       CFGR2: 0, SWPR: 0, SKR: 0}
    WRITABLE: ClassVar[dict[int, int]] = {MEMRMP: 0x107, CFGR1: 0xFFFF_FF01, **dict.fromkeys((0x08, 0x0C, 0x10, 0x14),
                                          0xFFFF), SCSR: 0x1, CFGR2: 0x10F, SWPR: 0xFFFF_FFFF, SKR: 0xFF}

    def port_of(self, line: int) -> str:
        """The port letter EXTICR selects for EXTI line `line` (0-15)."""
        field = self.regs[EXTICR1 + 4 * (line // 4)] >> (4 * (line % 4)) & 0xF
        return PORTS[field]

    def _exti(self) -> _LineSampler | None:
        try:
            exti = self.bus.peripheral("EXTI")
        except (BoardError, KeyError):
            return None
        return exti if hasattr(exti, "resample") else None

    def store(self, word: int, value: int, now: int) -> None:
        if EXTICR1 <= word <= 0x14:
            for i in range(4):
                if (value >> (4 * i) & 0xF) >= len(PORTS):
                    line = 4 * ((word - EXTICR1) // 4) + i
                    raise BoardError(f"SYSCFG EXTICR{(word - EXTICR1) // 4 + 1}: EXTI{line} = "
                                     f"{value >> (4 * i) & 0xF} selects no GPIO port of the part (0-6: PA-PG)")
            exti = self._exti()
            if exti is not None:
                exti.advance(now)  # the edges until now on the old selection
            self.regs[word] = value
            if exti is not None:
                exti.resample(now)
            return
        self.regs[word] = value
