"""The contract every peripheral model of the virtual STM32G4 board keeps (one model per file, one registry).

Time is the CPU's cycle count at SYSCLK (`now`, an int that only grows). The board runs the core in slices up to
the earliest `next_event` of all peripherals, then calls `advance(now)` on each; a model raises its interrupt
lines through `BoardBus.set_pending`. Register accesses reach `read`/`write` with the offset from `base`.
Register layouts, addresses and reset values follow RM0440 (STM32G4 reference manual).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Callable
from typing import ClassVar, Protocol, cast

from pmsm_hil.sim_target.firmware import FirmwareError


class BoardError(FirmwareError):
    """The firmware did what the virtual board cannot model or the chip would not allow (the message names the
    register or field, the address and the firmware's pc)."""


class BoardBus(Protocol):
    """What a peripheral model may ask of the board it sits on."""

    def set_pending(self, irq: int) -> None:
        """Pend the NVIC interrupt `irq` (position in the vector table after the 16 system exceptions)."""

    def clear_pending(self, irq: int) -> None:
        """Withdraw a level-sensitive request whose source flag was cleared."""

    def read_memory(self, address: int, size: int) -> bytes:
        """Bytes of the emulated address space (SRAM, message RAM), as the CPU would read them."""

    def write_memory(self, address: int, data: bytes) -> None:
        """Store bytes into the emulated address space (for example a received frame into FDCAN message RAM)."""

    def peripheral(self, name: str) -> Peripheral:
        """Another model on the board by its RM0440 name (`"TIM1"`, `"ADC12_COMMON"`), for trigger wiring."""

    @property
    def sysclk_hz(self) -> int:
        """The core clock as the firmware's RCC set-up left it [Hz]."""


class BoardServices(BoardBus, Protocol):
    """What the full board offers its own models beyond `BoardBus` (the clock tree, the analog front end, the
    encoder, the console); a model reaches it through `services(bus)`."""

    @property
    def hse_hz(self) -> int:
        """The board's HSE crystal or oscillator [Hz] (the board description)."""

    def set_hclk(self, hz: int) -> None:
        """The RCC model's report of a new core clock (SYSCLK through the AHB prescaler) [Hz]."""

    def log(self, source: str, line: str) -> None:
        """A line the firmware wrote (a console USART) for the run's log."""

    def analog_voltage(self, adc: str, channel: int, now: int) -> float:
        """The voltage at input `channel` of ADC `adc` at cycle `now` [V] (the board's analog front end); channel
        -1: the reference voltage VREF+."""

    def encoder_position(self, timer: str, now: int) -> int:
        """The quadrature edges counted so far by the encoder wired to `timer` (signed, 4 per line)."""


def services(bus: BoardBus) -> BoardServices:
    """`bus` as the full board (BoardError when a model that needs the board's services sits on a bare bus)."""
    if not hasattr(bus, "analog_voltage"):
        raise BoardError("this peripheral model needs the virtual board's services (clock tree, analog front end, "
                         "encoder, console), not a bare BoardBus")
    return cast(BoardServices, bus)


class Peripheral(ABC):
    """One memory-mapped peripheral at `base`, `size` bytes long; its state starts at RM0440's reset values."""

    name: str = ""
    base: int = 0
    size: int = 0x400
    #: `advance` does nothing before `next_event`'s cycle, and both change only through the model's register
    #: accesses, a core clock change (`BoardBus.sysclk_hz`) or a run-side input that calls `inputs_changed`: a
    #: board may then cache its next event and call it only when that event is due or after one of those
    EVENT_DRIVEN: ClassVar[bool] = False

    def __init__(self, bus: BoardBus) -> None:
        self.bus = bus
        self.reset()

    @abstractmethod
    def reset(self) -> None:
        """Return every register to its RM0440 reset value."""

    @abstractmethod
    def read(self, offset: int, size: int, now: int) -> int:
        """The value the CPU reads at `base + offset` (`size` 1, 2 or 4 bytes) at cycle `now`; raise
        `BoardError` naming the register for an offset the model does not implement."""

    @abstractmethod
    def write(self, offset: int, size: int, value: int, now: int) -> None:
        """The CPU stores `value` at `base + offset` at cycle `now` (write-1-to-clear, preload, etc. as RM0440
        says); raise `BoardError` naming the register for an offset the model does not implement."""

    def next_event(self, now: int) -> int | None:
        """The earliest cycle after `now` at which the model changes state by itself (a timer update, a
        conversion's end, a frame's arrival); None when nothing is due."""
        return None

    def advance(self, now: int) -> None:
        """Bring the model's state up to cycle `now`, raising the interrupts whose events fell in between (a
        model without events of its own has nothing to do)."""
        del now

    def inputs_changed(self) -> None:
        """The run side changed the model outside a register access (a frame received from the bus): a board that
        caches the model's next event (EVENT_DRIVEN) asks it again (a bus without `model_changed` caches none)."""
        notify = getattr(self.bus, "model_changed", None)
        if notify is not None:
            notify(self)


class BusMaster(BoardBus, Protocol):
    """A board on which a bus master (DMA) reaches any address as the CPU does: memory, or a peripheral's
    registers through its `read`/`write` (so a DMA read of a data register has the side effects of a CPU read).
    Optional: a model that needs it checks for `access` and names the lack in a BoardError."""

    def access(self, address: int, size: int, value: int | None = None, *, now: int) -> int:
        """Load `size` bytes at `address` (value None) and return them, or store `value` there and return it."""


PeripheralFactory = Callable[[BoardBus], Peripheral]
REGISTRY: dict[str, PeripheralFactory] = {}


def register(name: str) -> Callable[[type[Peripheral]], type[Peripheral]]:
    """Class decorator: make a model available to part descriptions under its RM0440 name."""

    def add(cls: type[Peripheral]) -> type[Peripheral]:
        if name in REGISTRY:
            raise BoardError(f"peripheral model {name!r} registered twice")
        cls.name = name
        REGISTRY[name] = cls
        return cls

    return add


__all__ = ["REGISTRY", "BoardBus", "BoardError", "BoardServices", "Peripheral", "PeripheralFactory", "register",
           "services"]
