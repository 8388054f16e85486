"""SysTick (Armv7-M B3.3): a 24-bit down-counter at HCLK (CLKSOURCE = 1) or HCLK/8, reloading from LOAD, setting
COUNTFLAG and pending exception 15 (TICKINT) at each wrap. Its time is the board's cycle count."""

from __future__ import annotations

from collections.abc import Callable

from pmsm_hil.sim_target.stm32g4.core_native import SysTickState


class SysTick:
    """CTRL/LOAD/VAL/CALIB at 0xE000E010..0xE000E01C."""

    def __init__(self, pend: Callable[[int], None], state: SysTickState | None = None) -> None:
        self._pend = pend
        #: the state (the C core's hil_systick_t: anchor, the cycle at which VAL was anchor_val; wraps so far)
        self.state = state if state is not None else SysTickState()

    @property
    def ctrl(self) -> int:
        return int(self.state.ctrl)

    @ctrl.setter
    def ctrl(self, value: int) -> None:
        self.state.ctrl = value

    @property
    def load(self) -> int:
        return int(self.state.load)

    @load.setter
    def load(self, value: int) -> None:
        self.state.load = value

    @property
    def countflag(self) -> bool:
        return bool(self.state.countflag)

    @countflag.setter
    def countflag(self, value: bool) -> None:
        self.state.countflag = int(value)

    @property
    def anchor(self) -> int:
        return int(self.state.anchor)

    @anchor.setter
    def anchor(self, value: int) -> None:
        self.state.anchor = value

    @property
    def anchor_val(self) -> int:
        return int(self.state.anchor_val)

    @anchor_val.setter
    def anchor_val(self, value: int) -> None:
        self.state.anchor_val = value

    @property
    def wraps(self) -> int:
        return int(self.state.wraps)

    @wraps.setter
    def wraps(self, value: int) -> None:
        self.state.wraps = value

    @property
    def enabled(self) -> bool:
        return bool(self.ctrl & 1)

    @property
    def divider(self) -> int:
        return 1 if self.ctrl & 4 else 8

    def value(self, now: int) -> int:
        """VAL at cycle `now`."""
        if not self.enabled:
            return self.anchor_val
        ticks = (now - self.anchor) // self.divider
        if ticks <= self.anchor_val:
            return self.anchor_val - ticks
        return self.load - (ticks - self.anchor_val - 1) % (self.load + 1)

    def next_event(self, now: int) -> int | None:
        """The cycle of the next wrap (VAL reaching 0 and reloading)."""
        if not self.enabled or (self.load == 0 and self.anchor_val == 0):
            return None
        period = (self.load + 1) * self.divider
        first = self.anchor + (self.anchor_val + 1) * self.divider  # reload after VAL = 0
        if now < first:
            return first
        return first + ((now - first) // period + 1) * period if self.load else None

    def advance(self, now: int) -> None:
        """Account every wrap up to `now` (one pend for any number of them, as on the chip)."""
        if not self.enabled or (self.load == 0 and self.anchor_val == 0):
            return
        first = self.anchor + (self.anchor_val + 1) * self.divider
        if now < first:
            return
        period = (self.load + 1) * self.divider
        wraps = 1 + (now - first) // period
        self.anchor = first + (wraps - 1) * period
        self.anchor_val = self.load
        self.wraps += wraps
        self.countflag = True
        if self.ctrl & 2:
            self._pend(self.anchor)

    def read(self, offset: int, now: int) -> int:
        if offset == 0x10:
            value = self.ctrl | (0x10000 if self.countflag else 0)
            self.countflag = False
            return value
        if offset == 0x14:
            return self.load
        if offset == 0x18:
            return self.value(now)
        return 0x4000_0000  # CALIB: NOREF, no TENMS figure

    def write(self, offset: int, value: int, now: int) -> None:
        if offset == 0x10:
            was = self.enabled
            self.anchor_val = self.value(now)
            self.ctrl = value & 7
            self.anchor = now
            if not was and self.enabled and self.anchor_val == 0:  # loads LOAD on the first tick
                self.anchor_val = 0
        elif offset == 0x14:
            self.anchor_val = self.value(now)
            self.anchor = now
            self.load = value & 0xFFFFFF
        elif offset == 0x18:  # any write clears VAL and COUNTFLAG
            self.anchor, self.anchor_val, self.countflag = now, 0, False
