"""GPIO ports A-G (RM0440 chapter 9): MODER/OTYPER/OSPEEDR/PUPDR/AFRL/AFRH as storage with their reset values,
ODR with BSRR/BRR, IDR = the outputs' levels on output pins and the board's input levels (default: the pull-up/down
level, else 0) on the others, LCKR accepted. Pins a board drives over time (hall sensors) follow an `InputDriver`
at the cycle of the read; EXTI asks the port when such a pin changes next (`next_input_change`), and a store to
MODER, ODR, BSRR or BRR brings EXTI up to its cycle before and after it, so an edge of the firmware's own output
pin (the pin's input stage follows its output, as on the chip) is taken at the store's cycle. The board reads a
pin through `pin_level`."""

from __future__ import annotations

from typing import Protocol

from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardBus, BoardError, Peripheral, register
from pmsm_hil.sim_target.stm32g4.peripherals.regs import RegisterFile

#: the registers whose store can change a pin's level: MODER, ODR, BSRR, BRR
LEVEL_WORDS = frozenset((0x00, 0x14, 0x18, 0x28))


class InputDriver(Protocol):
    """Something on the board that drives input pins over time (the hall sensors)."""

    def levels(self, port: str, now: int) -> int:
        """The driven pins' levels of GPIO`port` at cycle `now` (bit per pin)."""

    def next_change(self, port: str, mask: int, now: int) -> int | None:
        """The first cycle after `now` at which a driven pin of GPIO`port` in `mask` changes (None: none due)."""


class GpioPort(RegisterFile):
    base = 0x4800_0000
    size = 0x400
    MODER_RESET = 0xFFFF_FFFF
    OSPEEDR_RESET = 0
    PUPDR_RESET = 0

    def __init__(self, bus: BoardBus) -> None:
        #: levels the board drives onto input pins (bit per pin); None: the pull level
        self.inputs: int | None = None
        #: pins driven over time by `driver` (bit per pin), which override `inputs` on them
        self.driven = 0
        self.driver: InputDriver | None = None
        super().__init__(bus)

    @property
    def letter(self) -> str:
        """The port's letter ("A" for GPIOA)."""
        return self.name[-1]

    def drive(self, driver: InputDriver, mask: int) -> None:
        """Let `driver` set the levels of the pins in `mask` (input pins: an output pin reads its ODR)."""
        self.driver = driver
        self.driven = mask & 0xFFFF

    def reset(self) -> None:
        self.regs = {0x00: self.MODER_RESET, 0x04: 0, 0x08: self.OSPEEDR_RESET, 0x0C: self.PUPDR_RESET, 0x10: 0,
                     0x14: 0, 0x18: 0, 0x1C: 0, 0x20: 0, 0x24: 0, 0x28: 0}

    def output_mask(self) -> int:
        moder = self.regs[0x00]
        return sum(1 << pin for pin in range(16) if (moder >> (2 * pin)) & 3 == 1)

    def load(self, word: int, now: int) -> int:
        if word == 0x10:
            out = self.output_mask()
            if self.inputs is None:
                pupd = self.regs[0x0C]
                levels = sum(1 << pin for pin in range(16) if (pupd >> (2 * pin)) & 3 == 1)
            else:
                levels = self.inputs
            if self.driver is not None:
                levels = (levels & ~self.driven) | (self.driver.levels(self.letter, now) & self.driven)
            return (self.regs[0x14] & out) | (levels & ~out & 0xFFFF)
        if word in (0x18, 0x28):
            return 0
        return self.regs[word]

    def store(self, word: int, value: int, now: int) -> None:
        exti = self._exti() if word in LEVEL_WORDS else None
        if exti is not None:
            exti.advance(now)  # the edges until now, under the levels before the store
        self._apply(word, value)
        if exti is not None:
            exti.advance(now)  # the store's own edge, at its cycle

    def _exti(self) -> Peripheral | None:
        try:
            return self.bus.peripheral("EXTI")
        except BoardError:  # a part or test bench without EXTI
            return None

    def _apply(self, word: int, value: int) -> None:
        if word == 0x18:  # BSRR: set low half, reset high half (set wins)
            self.regs[0x14] = ((self.regs[0x14] & ~(value >> 16)) | value) & 0xFFFF
        elif word == 0x28:
            self.regs[0x14] &= ~value & 0xFFFF
        elif word == 0x10:
            return
        else:
            self.regs[word] = value & (0xFFFF if word == 0x14 else 0xFFFF_FFFF)

    def pin_level(self, pin: int, now: int = 0) -> bool:
        """The level of `pin` as IDR reads it at cycle `now`."""
        return bool(self.load(0x10, now) >> pin & 1)

    def next_input_change(self, mask: int, now: int) -> int | None:
        """The first cycle after `now` at which a driven input pin in `mask` changes level (None: none due)."""
        driven = mask & self.driven & ~self.output_mask()
        if self.driver is None or not driven:
            return None
        return self.driver.next_change(self.letter, driven, now)


@register("GPIOA")
class GpioA(GpioPort):
    base = 0x4800_0000
    MODER_RESET = 0xABFF_FFFF
    OSPEEDR_RESET = 0x0C00_0000
    PUPDR_RESET = 0x6400_0000


@register("GPIOB")
class GpioB(GpioPort):
    base = 0x4800_0400
    MODER_RESET = 0xFFFF_FEBF
    PUPDR_RESET = 0x0000_0100


@register("GPIOC")
class GpioC(GpioPort):
    base = 0x4800_0800


@register("GPIOD")
class GpioD(GpioPort):
    base = 0x4800_0C00


@register("GPIOE")
class GpioE(GpioPort):
    base = 0x4800_1000


@register("GPIOF")
class GpioF(GpioPort):
    base = 0x4800_1400


@register("GPIOG")
class GpioG(GpioPort):
    base = 0x4800_1800
