"""What the watchdog models share: the end of a run by a watchdog reset and the APB1 clock they count from."""

from __future__ import annotations

from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardBus, BoardError


class WatchdogResetError(BoardError):
    """A watchdog (WWDG or IWDG, named in the message) reset the chip: the run ends as a safety stop (exit 3)."""

    def __init__(self, watchdog: str, detail: str, now: int) -> None:
        self.watchdog = watchdog
        self.cycle = now
        super().__init__(f"watchdog reset by {watchdog} at cycle {now}: {detail}")


def apb1_divider(bus: BoardBus) -> int:
    """The APB1 prescaler the RCC model reports (PCLK1 = HCLK / divider); 1 on a board without an RCC model."""
    try:
        rcc = bus.peripheral("RCC")
    except (BoardError, KeyError):
        return 1
    divider = getattr(rcc, "apb_divider", None)
    return int(divider(1)) if callable(divider) else 1


__all__ = ["WatchdogResetError", "apb1_divider"]
