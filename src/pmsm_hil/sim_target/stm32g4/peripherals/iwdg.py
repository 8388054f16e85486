"""The independent watchdog of the STM32G474 (RM0440 "Independent watchdog") at 0x40003000: KR, PR, RLR, SR, WINR.

Started by software (key 0xCCCC; the hardware-watchdog option byte is not modelled), its 12-bit counter counts down
from 0xFFF at LSI / (4 * 2^PR), LSI taken as its nominal 32 kHz and converted to CPU cycles at the core clock of the
moment of each reload. Key 0x5555 opens PR, RLR and WINR to writes (any other key closes them), 0xAAAA reloads the
counter from RLR, and a WINR write reloads it too. SR's PVU/RVU/WVU stay set for UPDATE_LSI_PERIODS LSI periods after
a write of their register. The chip resets when the counter reaches 0 or when it is reloaded while above WINR; the
model ends the run with `WatchdogResetError` naming the cause. The IWDG has no interrupt.
"""

from __future__ import annotations

from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError, Peripheral, register
from pmsm_hil.sim_target.stm32g4.peripherals.watchdog import WatchdogResetError

KR, PR, RLR, SR, WINR = 0x0, 0x4, 0x8, 0xC, 0x10
KEY_RELOAD, KEY_ACCESS, KEY_START = 0xAAAA, 0x5555, 0xCCCC
PVU, RVU, WVU = 1, 2, 4
#: LSI, the IWDG's clock [Hz] (nominal; RM0440 and the datasheet give its spread)
LSI_HZ = 32_000
#: how long a prescaler, reload or window update stays in progress (SR flags) [LSI periods]
UPDATE_LSI_PERIODS = 6
RESET_COUNT = 0xFFF


@register("IWDG")
class Iwdg(Peripheral):
    """The independent watchdog: its counter as a function of time since the last reload."""

    base = 0x4000_3000
    size = 0x400
    #: its expiry is its only event
    EVENT_DRIVEN = True

    def reset(self) -> None:
        self.pr, self.rlr, self.winr = 0, RESET_COUNT, RESET_COUNT
        self.started = False
        self.unlocked = False
        #: the counter value `origin_count` at cycle `origin`
        self.origin, self.origin_count = 0, RESET_COUNT
        #: the flag of each update in progress -> the cycle it completes
        self.updating: dict[int, int] = {}
        #: writes to PR/RLR/WINR while they were write-protected, ignored as on the chip (count)
        self.ignored_writes = 0
        self.reloads = 0

    def _lsi_cycles(self, periods: int) -> int:
        """`periods` LSI periods in CPU cycles at the present core clock (rounded up)."""
        return -(-periods * self.bus.sysclk_hz // LSI_HZ)

    def _tick_cycles(self) -> tuple[int, int]:
        """One counter tick as the fraction (numerator, denominator) of CPU cycles."""
        return self.bus.sysclk_hz * (4 << min(self.pr, 6)), LSI_HZ

    def counter(self, now: int) -> int:
        """The 12-bit down-counter at cycle `now` (RESET_COUNT before the start)."""
        if not self.started:
            return self.origin_count
        num, den = self._tick_cycles()
        return max(0, self.origin_count - (max(0, now - self.origin) * den) // num)

    def expiry(self) -> int | None:
        """The cycle at which the counter reaches 0; None while stopped."""
        if not self.started:
            return None
        num, den = self._tick_cycles()
        return self.origin + -(-self.origin_count * num // den)

    def _reload(self, count: int, now: int, why: str | None) -> None:
        """The counter to `count` at `now`; `why` names a refresh that the window applies to."""
        if self.started and why is not None:
            value = self.counter(now)
            if value > self.winr:
                raise WatchdogResetError("IWDG", f"{why} with the counter at {value:#05x}, above the window WINR = "
                                         f"{self.winr:#05x}", now)
        self.origin, self.origin_count = now, count
        self.reloads += 1

    def read(self, offset: int, size: int, now: int) -> int:
        del size
        if offset == KR:
            return 0
        if offset == PR:
            return self.pr
        if offset == RLR:
            return self.rlr
        if offset == WINR:
            return self.winr
        if offset == SR:
            return sum(flag for flag, done in self.updating.items() if now < done)
        raise self._unknown(offset, "read")

    def write(self, offset: int, size: int, value: int, now: int) -> None:
        del size
        if offset == KR:
            self._key(value & 0xFFFF, now)
            return
        if offset not in (PR, RLR, WINR):
            if offset == SR:
                return  # read-only
            raise self._unknown(offset, "write")
        if not self.unlocked:
            self.ignored_writes += 1
            return
        done = now + self._lsi_cycles(UPDATE_LSI_PERIODS)
        if offset == PR:
            count = self.counter(now)
            self.pr = value & 7
            self.origin, self.origin_count = now, count  # the new prescaler counts from here
            self.updating[PVU] = done
        elif offset == RLR:
            self.rlr = value & 0xFFF
            self.updating[RVU] = done
        else:
            self.winr = value & 0xFFF
            self.updating[WVU] = done
            self._reload(self.rlr, now, None)

    def _key(self, key: int, now: int) -> None:
        self.unlocked = key == KEY_ACCESS
        if key == KEY_START and not self.started:
            self.started = True
            self.origin, self.origin_count = now, RESET_COUNT
        elif key == KEY_RELOAD:
            self._reload(self.rlr, now, "refreshed")

    def _unknown(self, offset: int, access: str) -> BoardError:
        return BoardError(f"{access} of IWDG at offset {offset:#05x} ({self.base + offset:#010x}), which the virtual "
                          "board does not model (KR, PR, RLR, SR, WINR)")

    def next_event(self, now: int) -> int | None:
        due = self.expiry()
        return None if due is None else max(due, now + 1)

    def advance(self, now: int) -> None:
        due = self.expiry()
        if due is not None and now >= due:
            raise WatchdogResetError("IWDG", f"counter reached 0, last reloaded at cycle {self.origin} with "
                                     f"{self.origin_count:#05x} (PR {self.pr}, LSI {LSI_HZ} Hz)", due)


__all__ = ["LSI_HZ", "Iwdg"]
