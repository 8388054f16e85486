"""EXTI (RM0440 chapter 15) for the GPIO lines 0-15: RTSR1/FTSR1 select the rising/falling edges of the pin that
SYSCFG EXTICR puts on each line, an edge sets its PR1 bit (write 1 to clear) and, with IMR1, asserts the line's NVIC
interrupt (EXTI0-4: IRQ 6-10, EXTI9_5: 23, EXTI15_10: 40) until PR1 is cleared; SWIER1 sets PR1 by software. The
edges come from the pins the board drives over time (the hall sensors): the model asks the GPIO port for the next
change (`next_event`) and compares the levels at each `advance`, so an edge is taken at its cycle (at most one basic
block late, as every event of the board); an edge of the firmware's own output pin is taken at the cycle of the
GPIO store that makes it (the port brings EXTI up to that cycle). EMR1, the lines
16-42 (IMR1 upper bits, IMR2, EMR2, RTSR2, FTSR2, SWIER2, PR2) and events are stored without effect."""

from __future__ import annotations

from typing import ClassVar

from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError, register
from pmsm_hil.sim_target.stm32g4.peripherals.gpio import GpioPort
from pmsm_hil.sim_target.stm32g4.peripherals.regs import RegisterFile
from pmsm_hil.sim_target.stm32g4.peripherals.syscfg import Syscfg

IMR1, EMR1, RTSR1, FTSR1, SWIER1, PR1 = 0x00, 0x04, 0x08, 0x0C, 0x10, 0x14
IMR2, EMR2, RTSR2, FTSR2, SWIER2, PR2 = 0x20, 0x24, 0x28, 0x2C, 0x30, 0x34
GPIO_LINES = 0xFFFF
#: NVIC line of each GPIO EXTI line (RM0440 table 97)
LINE_IRQ = (6, 7, 8, 9, 10, *([23] * 5), *([40] * 6))
#: the GPIO lines behind each of those NVIC lines
IRQ_LINES = {irq: sum(1 << line for line, i in enumerate(LINE_IRQ) if i == irq) for irq in set(LINE_IRQ)}


@register("EXTI")
class Exti(RegisterFile):
    base = 0x4001_0400
    size = 0x400
    RESET: ClassVar[dict[int, int]] = {IMR1: 0xFF82_0000, EMR1: 0, RTSR1: 0, FTSR1: 0, SWIER1: 0, PR1: 0,
                                       IMR2: 0x0000_043C, EMR2: 0, RTSR2: 0, FTSR2: 0, SWIER2: 0, PR2: 0}

    def reset(self) -> None:
        super().reset()
        #: the GPIO lines' levels when last sampled (bit per line)
        self.last = 0
        #: the GPIO lines with an edge selected (RTSR1 | FTSR1)
        self.edge_lines = 0
        #: the NVIC lines this model holds asserted
        self.asserted: set[int] = set()
        #: edges taken per GPIO line (PR1 set by a pin's edge, SWIER not counted)
        self.edges = [0] * 16

    # --- lines ------------------------------------------------------------------------------------------------

    def _ports(self) -> dict[str, int]:
        """The edge-selected lines by the GPIO port EXTICR puts on them."""
        syscfg = self.bus.peripheral("SYSCFG")
        if not isinstance(syscfg, Syscfg):
            raise BoardError("EXTI: the board has no SYSCFG model (EXTICR selects the GPIO lines' ports)")
        port_of = syscfg.port_of
        out: dict[str, int] = {}
        lines = self.edge_lines
        while lines:
            line = (lines & -lines).bit_length() - 1
            lines &= lines - 1
            letter = port_of(line)
            out[letter] = out.get(letter, 0) | 1 << line
        return out

    def _port(self, letter: str) -> GpioPort:
        port = self.bus.peripheral(f"GPIO{letter}")
        if not isinstance(port, GpioPort):
            raise BoardError(f"EXTI: GPIO{letter} is no GPIO port model")
        return port

    def levels(self, now: int) -> int:
        """The edge-selected lines' pin levels at cycle `now` (bit per line)."""
        out = 0
        for letter, lines in self._ports().items():
            out |= self._port(letter).load(0x10, now) & lines
        return out

    def resample(self, now: int) -> None:
        """Take the lines' levels at `now` as the reference for the next edge (after a change of the selection)."""
        self.edge_lines = (self.regs[RTSR1] | self.regs[FTSR1]) & GPIO_LINES
        self.last = self.levels(now) if self.edge_lines else 0

    def _update_irqs(self) -> None:
        flagged = self.regs[PR1] & self.regs[IMR1] & GPIO_LINES
        for irq, lines in IRQ_LINES.items():
            if flagged & lines:
                if irq not in self.asserted:
                    self.asserted.add(irq)
                    self.bus.set_pending(irq)
            elif irq in self.asserted:
                self.asserted.discard(irq)
                self.bus.clear_pending(irq)

    # --- Peripheral ---------------------------------------------------------------------------------------------

    def quiet(self) -> bool:
        """No GPIO line has an edge selected: neither `advance` nor `next_event` does anything until an RTSR1 or
        FTSR1 write selects one (SYSCFG's re-selection keeps the set of lines): the board need not call them
        meanwhile."""
        return not self.edge_lines

    def next_event(self, now: int) -> int | None:
        if not self.edge_lines:
            return None
        best: int | None = None
        for letter, lines in self._ports().items():
            port = self._port(letter)
            if (port.load(0x10, now) ^ self.last) & lines:  # changed since the last sample (a new trajectory)
                return now
            at = port.next_input_change(lines, now)
            if at is not None and (best is None or at < best):
                best = at
        return best

    def advance(self, now: int) -> None:
        if not self.edge_lines:
            return
        levels = self.levels(now)
        changed = levels ^ self.last
        if not changed:
            return
        self.last = levels
        hits = (changed & levels & self.regs[RTSR1]) | (changed & ~levels & self.regs[FTSR1])
        hits &= GPIO_LINES
        if hits:
            for line in range(16):
                if hits >> line & 1:
                    self.edges[line] += 1
            self.regs[PR1] |= hits
            self._update_irqs()

    def store(self, word: int, value: int, now: int) -> None:
        self.advance(now)  # the edges until now under the old configuration
        if word in (PR1, PR2):  # write 1 to clear
            self.regs[word] &= ~value
        elif word == SWIER1:
            self.regs[PR1] |= value & GPIO_LINES
        elif word == SWIER2:
            self.regs[PR2] |= value & self.regs[IMR2]
        else:
            self.regs[word] = value
        if word in (RTSR1, FTSR1):
            self.resample(now)
        self._update_irqs()

    def load(self, word: int, now: int) -> int:
        if word == PR1:
            self.advance(now)
        if word in (SWIER1, SWIER2):
            return 0
        return self.regs[word]
