"""The window watchdog of the STM32G474 (RM0440 "System window watchdog") at 0x40002C00: CR, CFR, SR, the early
wakeup interrupt WWDG (IRQ 0).

The 7-bit counter counts down at PCLK1 / 4096 / 2^WDGTB, free-running; the ticks are counted from the last write of
CR or CFR (the prescaler's phase on the chip is not known to the firmware either). With WDGA set, the chip resets
when the counter falls from 0x40 to 0x3F, when CR is written while the counter is above the window W, or when CR is
written with T6 clear; the model ends the run with `WatchdogResetError` naming the cause. EWIF is set when the
counter reaches 0x40 and pends the interrupt when EWI is set.
"""

from __future__ import annotations

from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError, Peripheral, register
from pmsm_hil.sim_target.stm32g4.peripherals.watchdog import WatchdogResetError, apb1_divider

CR, CFR, SR = 0x0, 0x4, 0x8
IRQ = 0
WDGA, T_MASK, T6 = 1 << 7, 0x7F, 0x40
W_MASK, EWI, WDGTB_SHIFT = 0x7F, 1 << 9, 11
CFR_WRITABLE = 0x3A7F
EWIF = 1
PCLK_DIVIDER = 4096


@register("WWDG")
class Wwdg(Peripheral):
    """The window watchdog: its counter as a function of time since the last write."""

    base = 0x4000_2C00
    size = 0x400
    #: the early wakeup and the reset are its only events
    EVENT_DRIVEN = True

    def reset(self) -> None:
        self.cfr = 0x7F
        self.sr = 0
        self.active = False
        #: the counter value `origin_count` at cycle `origin`, counting down one every `period` cycles
        self.origin, self.origin_count = 0, 0x7F
        self.period = PCLK_DIVIDER
        self._ewi_done = False
        self._line_up = False
        #: refreshes (CR writes while active) (count)
        self.refreshes = 0

    def _ticks(self, now: int) -> int:
        return max(0, now - self.origin) // self.period

    def counter(self, now: int) -> int:
        """The 7-bit down-counter at cycle `now` (free-running, wrapping)."""
        return (self.origin_count - self._ticks(now)) & T_MASK

    def _anchor(self, count: int, now: int) -> None:
        self.origin, self.origin_count = now, count
        self.period = apb1_divider(self.bus) * PCLK_DIVIDER << ((self.cfr >> WDGTB_SHIFT) & 7)
        self._ewi_done = count <= T6 - 1

    def read(self, offset: int, size: int, now: int) -> int:
        del size
        if offset == CR:
            return (WDGA if self.active else 0) | self.counter(now)
        if offset == CFR:
            return self.cfr
        if offset == SR:
            return self.sr
        raise self._unknown(offset, "read")

    def write(self, offset: int, size: int, value: int, now: int) -> None:
        del size
        if offset == CR:
            self._write_cr(value, now)
        elif offset == CFR:
            count = self.counter(now)
            self.cfr = (value & CFR_WRITABLE) | (self.cfr & EWI)  # EWI is cleared only by a reset
            self._anchor(count, now)
        elif offset == SR:
            self.sr &= value  # rc_w0
            self._update_line()
        else:
            raise self._unknown(offset, "write")

    def _write_cr(self, value: int, now: int) -> None:
        if self.active:
            count = self.counter(now)
            window = self.cfr & W_MASK
            if count > window:
                raise WatchdogResetError("WWDG", f"refreshed with the counter at {count:#04x}, above the window "
                                         f"W = {window:#04x}", now)
            self.refreshes += 1
        self.active = self.active or bool(value & WDGA)
        self._anchor(value & T_MASK, now)
        if self.active and not value & T6:
            raise WatchdogResetError("WWDG", f"CR written with T6 clear ({value & 0xFF:#04x})", now)

    def _unknown(self, offset: int, access: str) -> BoardError:
        return BoardError(f"{access} of WWDG at offset {offset:#05x} ({self.base + offset:#010x}), which the virtual "
                          "board does not model (CR, CFR, SR)")

    def _at_count(self, count: int) -> int:
        """The cycle at which the counter reaches `count` (below the origin value)."""
        return self.origin + (self.origin_count - count) * self.period

    def next_event(self, now: int) -> int | None:
        if not self.active:
            return None
        due = self._at_count(T6 - 1)
        if not self._ewi_done:
            due = self._at_count(T6)
        return max(due, now + 1)

    def advance(self, now: int) -> None:
        if not self.active:
            return
        if not self._ewi_done and now >= self._at_count(T6):
            self._ewi_done = True
            self.sr |= EWIF
            self._update_line()
        if now >= self._at_count(T6 - 1):
            raise WatchdogResetError("WWDG", f"counter fell to 0x3f, last written at cycle {self.origin} with "
                                     f"{self.origin_count:#04x} (one tick every {self.period} cycles)",
                                     self._at_count(T6 - 1))

    def _update_line(self) -> None:
        up = bool(self.sr & EWIF and self.cfr & EWI)
        if up and not self._line_up:
            self.bus.set_pending(IRQ)
        elif self._line_up and not up:
            self.bus.clear_pending(IRQ)
        self._line_up = up


__all__ = ["Wwdg"]
