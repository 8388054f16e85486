"""USART2 as a console (RM0440 chapter 37): what the firmware writes to TDR, line by line, goes to the run's log
(`BoardBus.log`); TXE and TC are always set (the line is infinitely fast), TEACK/REACK follow TE/RE, the receiver
never receives. TXE/TC interrupts follow their enables as levels."""

from __future__ import annotations

from typing import ClassVar

from pmsm_hil.sim_target.stm32g4.part import IRQ
from pmsm_hil.sim_target.stm32g4.peripherals.base import register, services
from pmsm_hil.sim_target.stm32g4.peripherals.regs import RegisterFile

MAX_LINE = 1000


@register("USART2")
class Usart2(RegisterFile):
    base = 0x4000_4400
    size = 0x400
    IRQ_LINE = IRQ["USART2"]
    RESET: ClassVar[dict[int, int]] = {
        0x00: 0, 0x04: 0, 0x08: 0, 0x0C: 0, 0x10: 0, 0x14: 0, 0x18: 0, 0x1C: 0x0000_00C0, 0x20: 0, 0x24: 0,
             0x28: 0, 0x2C: 0}

    def reset(self) -> None:
        super().reset()
        self.line = bytearray()

    def load(self, word: int, now: int) -> int:
        if word == 0x1C:
            cr1 = self.regs[0x00]
            return 0xC0 | (1 << 21 if cr1 & 8 else 0) | (1 << 22 if cr1 & 4 else 0) | (1 << 23 if cr1 & 1 else 0)
        return self.regs[word]

    def store(self, word: int, value: int, now: int) -> None:
        if word == 0x28:
            self._put(value & 0xFF)
            return
        if word in (0x1C, 0x24, 0x18, 0x20):
            return
        self.regs[word] = value
        if word == 0x00:
            if value & 1 and value & (0xC0):  # TXEIE/TCIE with TXE/TC always set: the line is asserted
                self.bus.set_pending(self.IRQ_LINE)
            else:
                self.bus.clear_pending(self.IRQ_LINE)

    def _put(self, byte: int) -> None:
        if byte == 0x0A or len(self.line) >= MAX_LINE:
            services(self.bus).log(self.name, self.line.decode("utf-8", "replace").rstrip("\r"))
            self.line.clear()
            if byte == 0x0A:
                return
        self.line.append(byte)
