"""TIM1, the advanced-control timer (RM0440 chapter 28), as far as a motor drive uses it: the counter at the
timer clock (= HCLK for APB2 prescalers 1 and 2) through PSC, up, down and centre-aligned modes (CMS 1-3),
ARR with and without preload (ARPE), the repetition counter (an update event every RCR + 1 over/underflows),
CCR1-6 with and without preload (OCxPE: a value written after the update event applies from the next one, as
on the chip), PWM mode 1/2 and toggle on OC1-6REF, BDTR dead time (DTG, CKD) and MOE, UIF/CCxIF and their
interrupts (TIM1_UP_TIM16, TIM1_CC), UG, and the trigger outputs TRGO (MMS) and TRGO2 (MMS2) and the CC4 event as
ADC triggers (`subscribe`).

Event-driven: the counter is computed from the cycle count, never ticked. Counter segments (a count up or down
between two over/underflows) end at their own instants; compare matches are instants inside a segment and are
events only for a channel someone observes (its interrupt enabled, or an ADC trigger made of it): CCxIF of an
unobserved channel is not set. The break input BRK from the BKIN pin (AF1.BKINE, AF1.BKINP; the board drives the
pin from the plant's overcurrent, `set_break_pin`): with BDTR.BKE set and BRK at BDTR.BKP's level, MOE is cleared
and held cleared (the outputs go to their idle state), SR.BIF is set (it cannot be cleared while BRK is active) and
raises TIM1_BRK_TIM15 with DIER.BIE; BDTR.AOE sets MOE again at the next update once BRK is inactive (the break
filter BKF is taken as none). Input capture, one-pulse mode, slave modes, encoder mode, DMA, the second break input
BRK2, COM events and dithering are not modelled (a write that enables one is refused naming the field).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import ClassVar

from pmsm_hil.sim_target.stm32g4 import periph_native
from pmsm_hil.sim_target.stm32g4.part import IRQ
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardBus, BoardError, register
from pmsm_hil.sim_target.stm32g4.peripherals.regs import RegisterFile

CR1, CR2, SMCR, DIER, SR, EGR, CCMR1, CCMR2, CCER, CNT, PSC, ARR, RCR = (
    0x00, 0x04, 0x08, 0x0C, 0x10, 0x14, 0x18, 0x1C, 0x20, 0x24, 0x28, 0x2C, 0x30)
CCR_OFFSETS = (0x34, 0x38, 0x3C, 0x40, 0x48, 0x4C)  # CCR1-4, CCR5, CCR6
BDTR, CCMR3, DTR2, ECR, TISEL, AF1, AF2, OR1, DCR, DMAR = (
    0x44, 0x50, 0x54, 0x58, 0x5C, 0x60, 0x64, 0x68, 0x3DC, 0x3E0)
PWM1, PWM2, TOGGLE = 6, 7, 3
#: BDTR fields of the break function, SR.BIF, DIER.BIE, AF1.BKINE and AF1.BKINP
OSSI, BKE, BKP, AOE, MOE, BK2E = 1 << 10, 1 << 12, 1 << 13, 1 << 14, 1 << 15, 1 << 24
BIF, BIE, BKINE, BKINP = 1 << 7, 1 << 7, 1 << 0, 1 << 9
#: registers whose writes may move the current segment's planned events
_PLAN_WORDS = frozenset((CR1, CR2, SMCR, DIER, CCMR1, CCMR2, CCMR3, CCER, CNT, PSC, ARR))
#: signals an ADC can take as its trigger
SIGNALS = ("TRGO", "TRGO2", "CC1", "CC2", "CC3", "CC4")
Listener = Callable[[str, bool, int], None]  # (signal, rising edge, cycle)
#: the interrupt lines and the SR flags that raise them (with their DIER enables)
_LINES = ((IRQ["TIM1_UP_TIM16"], 1), (IRQ["TIM1_CC"], 0x1E), (IRQ["TIM1_BRK_TIM15"], BIF))


@register("TIM1")
class Tim1(RegisterFile):
    base = 0x4001_2C00
    size = 0x400
    #: the models whose events are exact (nothing changes before `next_event` but through an access to one of them,
    #: which advances it first) and that drive each other (TIM1's triggers start the ADCs' conversions): the board
    #: advances them together and skips them while their earliest event is ahead
    EVENT_GROUP: ClassVar[str] = "TIM1"
    RESET: ClassVar[dict[int, int]] = {
        CR1: 0, CR2: 0, SMCR: 0, DIER: 0, SR: 0, EGR: 0, CCMR1: 0, CCMR2: 0, CCER: 0, CNT: 0, PSC: 0, ARR: 0xFFFF,
        RCR: 0, BDTR: 0, CCMR3: 0, DTR2: 0, ECR: 0, TISEL: 0, AF1: 1, AF2: 1, OR1: 0, DCR: 0, DMAR: 0,
        **dict.fromkeys(CCR_OFFSETS, 0)}

    def __new__(cls, bus: BoardBus) -> Tim1:
        """The model in C (tim1_native.NativeTim1) while periph_native.NATIVE is set, else this reference."""
        del bus
        if cls is Tim1 and periph_native.NATIVE:
            from pmsm_hil.sim_target.stm32g4.peripherals.tim1_native import NativeTim1
            cls = NativeTim1
        return super().__new__(cls)

    def reset(self) -> None:
        super().reset()
        self.psc = 0  # active prescaler (PSC is always preloaded)
        self.arr = 0xFFFF  # active auto-reload
        self.ccr = [0] * 6  # active compare values
        self.rep = 0  # repetition down-counter
        self.running = False
        self.seg_start = 0  # cycle at which the current segment began
        self.seg_from = 0  # counter value then
        self.seg_dir = 1  # +1 up, -1 down
        self.done_until = 0  # events up to this cycle are processed
        self.frozen_cnt = 0
        self.listeners: dict[str, list[Listener]] = {}
        self.ocref = [False] * 6
        self.updates = 0  # update events so far
        self.last_update = -1  # cycle of the last update event
        self.last_trigger = -1  # cycle of the last ADC trigger this timer emitted
        self.late_writes = 0  # periods whose compare values were written after the update that followed the trigger
        self.first_late_update: int | None = None  # the update count at the first late period
        self._late_counted_at = -2
        self._plan: list[tuple[int, int]] | None = None  # the current segment's observed matches (cycle, channel)
        self._plan_end = 0  # the segment's end when the plan was made [cycle] (valid while the plan is)
        self._watched: tuple[bool, ...] | None = None  # which channels are observed (until a configuration write)
        self.break_pin: bool | None = None  # the BKIN pin's level (None: nothing drives it, BRK never active)
        self.break_trips = 0  # times BRK went active with BKE set
        self._lines_on = [False] * len(_LINES)  # which interrupt lines this model asserts

    # --- configuration helpers -------------------------------------------------------------------------------------

    @property
    def cms(self) -> int:
        return self.regs[CR1] >> 5 & 3

    @property
    def tick(self) -> int:
        """Cycles per counter tick."""
        return self.psc + 1

    def _oc_mode(self, ch: int) -> int:
        if ch < 4:
            reg = self.regs[CCMR1 if ch < 2 else CCMR2]
            shift = 8 * (ch & 1)
        else:
            reg = self.regs[CCMR3]
            shift = 8 * (ch - 4)
        return (reg >> (shift + 4) & 7) | (reg >> (shift + 16) & 1) << 3

    def _preloaded(self, ch: int) -> bool:
        if ch < 4:
            reg = self.regs[CCMR1 if ch < 2 else CCMR2]
            return bool(reg >> (8 * (ch & 1) + 3) & 1)
        return bool(self.regs[CCMR3] >> (8 * (ch - 4) + 3) & 1)

    def carrier_cycles(self) -> int:
        """One PWM period [cycles]: 2·ARR ticks centre-aligned, ARR + 1 edge-aligned."""
        return (2 * self.arr if self.cms else self.arr + 1) * self.tick

    def update_period_cycles(self) -> int:
        """Cycles between update events (the repetition counter included)."""
        half = self.arr * self.tick if self.cms else (self.arr + 1) * self.tick
        return half * (self.regs[RCR] + 1)

    def dead_time_s(self, hclk_hz: int) -> float:
        """BDTR.DTG as seconds (RM0440 28.6.21), tDTS from CR1.CKD."""
        dtg = self.regs[BDTR] & 0xFF
        t_dts = (1, 2, 4, 4)[self.regs[CR1] >> 8 & 3] / hclk_hz
        if dtg >> 7 == 0:
            return dtg * t_dts
        if dtg >> 6 == 2:
            return (64 + (dtg & 0x3F)) * 2 * t_dts
        if dtg >> 5 == 6:
            return (32 + (dtg & 0x1F)) * 8 * t_dts
        return (32 + (dtg & 0x1F)) * 16 * t_dts

    @property
    def moe(self) -> bool:
        return bool(self.regs[BDTR] >> 15 & 1)

    def duty(self, ch: int) -> float:
        """The fraction of a carrier period the OCx output is active-high with the compare value in force
        (centre-aligned or edge-aligned PWM mode 1/2, CCxP polarity)."""
        mode = self._oc_mode(ch)
        ccr, arr = self.ccr[ch], self.arr
        span = arr if self.cms else arr + 1
        ref_high = min(max(ccr / span, 0.0), 1.0) if span else 0.0
        if mode == PWM2:
            ref_high = 1.0 - ref_high
        elif mode != PWM1:
            ref_high = 1.0 if mode == 5 else 0.0  # forced active / anything else inactive
        if self.regs[CCER] >> (4 * ch + 1) & 1:  # CCxP: active low
            ref_high = 1.0 - ref_high
        return ref_high

    def compare_duties(self, channels: Sequence[int], currents: Sequence[float], hclk_hz: int,
                       carrier_s: float) -> tuple[float, ...] | None:
        """The outputs a board link reads once a period: with MOE set, the duties of `channels` (0-based) with the
        compare values in force (PWM mode, polarity; 0.5 for a disabled output), each shortened or lengthened by the
        dead time according to the sign of its phase current in `currents` [A] when its complementary output is
        on, clamped to 0..1 (`hclk_hz` [Hz] the timer's clock, `carrier_s` [s] its period); None with MOE clear."""
        if not self.moe:
            return None
        dead = self.dead_time_s(hclk_hz) / carrier_s
        ccer = self.regs[CCER]
        out = []
        for ch, current in zip(channels, currents, strict=True):
            d = self.duty(ch) if ccer >> (4 * ch) & 1 else 0.5
            if ccer >> (4 * ch + 2) & 1 and dead and current != 0.0:
                d -= math.copysign(dead, current)
            out.append(min(max(d, 0.0), 1.0))
        return tuple(out)

    def trip_break(self) -> None:
        """The break input went active: MOE cleared, BIF set (its interrupt on TIM1_BRK when BIE)."""
        self.regs[BDTR] &= ~MOE
        self.regs[SR] |= BIF
        self.break_trips += 1
        self._irqs()

    def break_active(self) -> bool:
        """BRK is active: BKE set, the BKIN pin enabled (AF1.BKINE) and at BKP's level (through AF1.BKINP)."""
        pin = self.break_pin
        bdtr, af1 = self.regs[BDTR], self.regs[AF1]
        if pin is None or not bdtr & BKE or not af1 & BKINE:
            return False
        return (pin != bool(af1 & BKINP)) == bool(bdtr & BKP)

    def set_break_pin(self, level: bool, now: int) -> None:
        """The board drives the BKIN pin to `level` (high True) at cycle `now`; an edge that makes BRK active
        trips the break."""
        self.advance(now)
        was = self.break_active()
        self.break_pin = level
        if self.break_active() and not was:
            self.trip_break()

    def output_enabled(self, ch: int) -> bool:
        return bool(self.regs[CCER] >> (4 * ch) & 1)

    # --- observers ------------------------------------------------------------------------------------------------

    def subscribe(self, signal: str, listener: Listener) -> None:
        """Call `listener(signal, rising, cycle)` at each edge of `signal` (SIGNALS)."""
        if signal not in SIGNALS:
            raise BoardError(f"TIM1 has no trigger signal {signal!r}")
        if listener not in self.listeners.setdefault(signal, []):
            self.listeners[signal].append(listener)
        self._plan = self._watched = None

    def unsubscribe(self, listener: Listener) -> None:
        for group in self.listeners.values():
            if listener in group:
                group.remove(listener)
        self._plan = self._watched = None

    def _emit(self, signal: str, rising: bool, at: int) -> None:
        for listener in self.listeners.get(signal, ()):
            if rising:
                self.last_trigger = at
            listener(signal, rising, at)

    def _pulse(self, signal: str, at: int) -> None:
        self._emit(signal, True, at)
        self._emit(signal, False, at)

    def _observed(self, ch: int) -> bool:
        dier = self.regs[DIER]
        if ch < 4 and dier >> (ch + 1) & 1:
            return True
        if self.listeners.get(f"CC{ch + 1}"):
            return True
        mms, mms2 = self.regs[CR2] >> 4 & 7, self.regs[CR2] >> 20 & 0xF
        if self.listeners.get("TRGO") and (mms == 4 + ch or (mms == 3 and ch == 0)):
            return True
        if self.listeners.get("TRGO2"):
            if mms2 == 4 + ch or (mms2 == 3 and ch == 0):
                return True
            if ch == 3 and mms2 in (10, 12, 13):
                return True
            if ch == 5 and mms2 in (11, 12, 13, 14, 15):
                return True
            if ch == 4 and mms2 in (14, 15):
                return True
        return False

    # --- the counter ----------------------------------------------------------------------------------------------

    def counter(self, now: int) -> int:
        if not self.running:
            return self.frozen_cnt
        self.advance(now)
        ticks = (now - self.seg_start) // self.tick
        return self.seg_from + self.seg_dir * ticks

    def _segment_ticks(self) -> int:
        """Ticks from the segment's start to its end event (overflow or underflow)."""
        if self.cms:
            return self.arr - self.seg_from if self.seg_dir > 0 else self.seg_from
        return self.arr + 1 - self.seg_from if self.seg_dir > 0 else self.seg_from + 1

    def _segment_end(self) -> int:
        return self.seg_start + max(self._segment_ticks(), 1) * self.tick

    def _matches(self) -> list[tuple[int, int]]:
        """(cycle, channel) of the observed compare matches in the current segment after `done_until` (planned once
        per segment and after a write that moves them)."""
        plan = self._plan
        if plan is None:
            plan = []
            end_ticks = self._segment_ticks()
            watched = self._watched
            if watched is None:
                watched = self._watched = tuple(self._observed(ch) for ch in range(6))
            for ch in range(6):
                if not watched[ch]:
                    continue
                c = self.ccr[ch]
                offset = (c - self.seg_from) if self.seg_dir > 0 else (self.seg_from - c)
                if 0 <= offset <= end_ticks and not (self.cms and self.seg_dir < 0 and offset == 0):
                    plan.append((self.seg_start + offset * self.tick, ch))
            plan.sort()
            self._plan = plan
            self._plan_end = self._segment_end()
        done = self.done_until
        while plan and plan[0][0] <= done:
            plan.pop(0)
        return plan

    def next_event(self, now: int) -> int | None:
        if not self.running:
            return None
        plan = self._plan
        if plan is not None and (not plan or plan[0][0] > self.done_until):  # the plan and its end stand
            return min(plan[0][0], self._plan_end) if plan else self._plan_end
        matches = self._matches()
        end = self._segment_end()
        return min(matches[0][0], end) if matches else end  #

    def advance(self, now: int) -> None:
        plan = self._plan
        if plan is not None and self.running and self._plan_end > now and (not plan or plan[0][0] > now):
            # nothing due: the segment's plan stands (every change of the segment or its matches drops it)
            if now > self.done_until:
                self.done_until = now
            return
        while self.running:
            end = self.seg_start + max(self._segment_ticks(), 1) * self.tick
            plan = self._matches()
            while plan and plan[0][0] <= now:
                at, ch = plan.pop(0)
                self._match(ch, at)
                self.done_until = at
            if end > now:
                if now > self.done_until:
                    self.done_until = now
                return
            self._segment_done(end)

    def _match(self, ch: int, at: int) -> None:
        """Counter = CCRx+1 at `at`: CCxIF (by CMS direction), the CCx pulse, OCxREF edges."""
        up = self.seg_dir > 0
        cms = self.cms
        if ch < 4 and (cms in (0, 3) or (cms == 1 and not up) or (cms == 2 and up)):
            self._flag(1 << (ch + 1), at)
        if ch < 4:
            self._pulse(f"CC{ch + 1}", at)
        mode = self._oc_mode(ch)
        old = self.ocref[ch]
        if mode == PWM1:
            new = not up
        elif mode == PWM2:
            new = up
        elif mode == TOGGLE:
            new = not old
        else:
            new = old
        self.ocref[ch] = new
        cr2 = self.regs[CR2]
        mms, mms2 = cr2 >> 4 & 7, cr2 >> 20 & 0xF
        if mms == 3 and ch == 0:
            self._pulse("TRGO", at)
        if mms2 == 3 and ch == 0:
            self._pulse("TRGO2", at)
        if new != old:
            if mms == 4 + ch:
                self._emit("TRGO", new, at)
            if mms2 == 4 + ch:
                self._emit("TRGO2", new, at)
            if (mms2 == 10 and ch == 3) or (mms2 == 11 and ch == 5):
                self._pulse("TRGO2", at)
            if new and ((mms2 in (12, 13) and ch == 3) or (mms2 in (14, 15) and ch == 4)):
                self._pulse("TRGO2", at)
            if ch == 5 and ((mms2 in (12, 14) and new) or (mms2 in (13, 15) and not new)):
                self._pulse("TRGO2", at)

    def _segment_done(self, at: int) -> None:
        """Overflow or underflow at `at`: the repetition counter, the update event, the next segment."""
        self.done_until = at
        self._plan = None
        if self.cms:
            self.seg_from, self.seg_dir = (self.arr, -1) if self.seg_dir > 0 else (0, 1)
        else:
            self.seg_from = 0 if self.seg_dir > 0 else self.arr
        self.seg_start = at
        if self.rep == 0:
            self.rep = self.regs[RCR]
            if not self.regs[CR1] >> 1 & 1:  # UDIS
                self._update(at)
                if not self.cms:
                    self.seg_from = 0 if self.seg_dir > 0 else self.arr
        else:
            self.rep -= 1

    def _update(self, at: int) -> None:
        """The update event: preloads transferred, UIF, TRGO/TRGO2 on update."""
        self.psc = self.regs[PSC]
        self.arr = self.regs[ARR]
        for ch in range(6):
            if self._preloaded(ch):
                self.ccr[ch] = self.regs[CCR_OFFSETS[ch]]
        self.updates += 1
        self.last_update = at
        if self.regs[BDTR] & AOE and not self.regs[BDTR] & MOE and not self.break_active():
            self.regs[BDTR] |= MOE  # automatic output enable
        self._flag(1, at)
        cr2 = self.regs[CR2]
        if cr2 >> 4 & 7 == 2:
            self._pulse("TRGO", at)
        if cr2 >> 20 & 0xF == 2:
            self._pulse("TRGO2", at)

    def _flag(self, bits: int, at: int) -> None:
        self.regs[SR] |= bits
        self._irqs()

    def _irqs(self) -> None:
        """Each line asserted while a flag and its enable are set (pending it again), withdrawn when that ends."""
        sr, dier, on = self.regs[SR], self.regs[DIER], self._lines_on
        for i, (line, mask) in enumerate(_LINES):
            if sr & dier & mask:
                on[i] = True
                self.bus.set_pending(line)
            elif on[i]:
                on[i] = False
                self.bus.clear_pending(line)

    # --- registers ------------------------------------------------------------------------------------------------

    def read(self, offset: int, size: int, now: int) -> int:
        if size == 4 and offset in self.regs:  # an aligned word (the register file's own path, one call fewer)
            return self.load(offset, now)
        return super().read(offset, size, now)

    def load(self, word: int, now: int) -> int:
        if word in (SR, CNT):
            self.advance(now)
        if word == CNT:
            return self.counter(now) & 0xFFFF
        if word == EGR:
            return 0
        if word == CR1:
            return self.regs[CR1] & ~(1 << 4) | ((1 << 4) if self.seg_dir < 0 else 0)
        return self.regs[word]

    def store(self, word: int, value: int, now: int) -> None:
        self.advance(now)
        if word in _PLAN_WORDS or (word in CCR_OFFSETS and not self._preloaded(CCR_OFFSETS.index(word))):
            self._plan = None  # a compare in force, a mode, an enable or a trigger selection moves the events
            self._watched = None
        if word == SR:  # rc_w0
            self.regs[SR] &= value | (BIF if self.break_active() else 0)  # BIF stays set while BRK is active
            self._irqs()
            return
        if word == BDTR:
            if value & BK2E:
                raise BoardError("TIM1.BDTR.BK2E: the second break input BRK2 is not modelled")
            was = self.break_active()
            self.regs[BDTR] = value
            if self.break_active():  # MOE cannot be set while BRK is active
                self.regs[BDTR] &= ~MOE
                if not was:
                    self.trip_break()
            return
        if word == EGR:
            if value & 1:  # UG: reinitialise the counter and update
                self._restart(now, 0 if not (self.regs[CR1] >> 4 & 1) or self.cms else self.regs[ARR])
                self.rep = self.regs[RCR]
                self._update(now)
            if value & ~1 & 0xFF:
                raise BoardError("TIM1.EGR: only UG (bit 0) is modelled")
            return
        if word == CNT:
            self._restart(now, value & 0xFFFF)
            return
        if word == SMCR and value & 0x0001_0007:
            raise BoardError("TIM1.SMCR.SMS: slave and encoder modes of TIM1 are not modelled")
        if word == CR1:
            if value & 8:
                raise BoardError("TIM1.CR1.OPM: one-pulse mode is not modelled")
            was = self.running
            old_dir = self.regs[CR1] >> 4 & 1
            self.regs[CR1] = value & 0x1FFF
            if not self.regs[CR1] >> 7 & 1:
                self.arr = self.regs[ARR]
            if value & 1 and not was:
                self.running = True
                self._restart(now, self.frozen_cnt)
            elif not value & 1 and was:
                self.frozen_cnt = self.counter(now)
                self.running = False
            elif not self.cms and (value >> 4 & 1) != old_dir:
                self._restart(now, self.counter(now))
            return
        if word == DIER:
            self.regs[DIER] = value
            self._irqs()
            return
        if word in CCR_OFFSETS:
            ch = CCR_OFFSETS.index(word)
            self.regs[word] = value & 0xFFFF
            if ch < 3:
                self._note_compare_write(now)
            if not self._preloaded(ch):
                self.ccr[ch] = value & 0xFFFF
            return
        if word == ARR:
            self.regs[ARR] = value & 0xFFFF
            if not self.regs[CR1] >> 7 & 1:
                self.arr = value & 0xFFFF
            return
        self.regs[word] = value

    def _restart(self, now: int, cnt: int) -> None:
        self._plan = None
        self.frozen_cnt = cnt
        self.seg_start, self.seg_from = now, cnt
        self.seg_dir = -1 if (not self.cms and self.regs[CR1] >> 4 & 1) else 1
        if self.cms and cnt >= self.arr:
            self.seg_dir = -1
        self.done_until = now

    def _note_compare_write(self, now: int) -> None:
        """A compare value written after the update that followed the last ADC trigger lands a period late."""
        if self.last_trigger < 0 or self.last_update <= self.last_trigger or not self.running:
            return
        if self._late_counted_at == self.last_update:
            return
        self._late_counted_at = self.last_update
        self.late_writes += 1
        if self.first_late_update is None:
            self.first_late_update = self.updates
