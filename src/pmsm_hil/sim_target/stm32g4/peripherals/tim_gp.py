"""TIM3 and TIM4, general-purpose timers (RM0440 chapter 29), as a drive uses them: encoder mode (SMCR.SMS 1, 2
or 3: x2 on TI1 or TI2, x4 on both) counting the board's encoder (`BoardBus.encoder_position`) modulo ARR + 1,
with DIR following the rotation, and otherwise a plain up-counter at the timer clock through PSC with the update
interrupt (UIF/UIE) for a time base. Capture/compare, other slave modes, DMA and one-pulse mode are not
modelled (a write enabling one is refused naming the field)."""

from __future__ import annotations

from typing import ClassVar

from pmsm_hil.sim_target.stm32g4.part import IRQ
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError, register, services
from pmsm_hil.sim_target.stm32g4.peripherals.regs import RegisterFile

CR1, CR2, SMCR, DIER, SR, EGR, CCMR1, CCMR2, CCER, CNT, PSC, ARR = (
    0x00, 0x04, 0x08, 0x0C, 0x10, 0x14, 0x18, 0x1C, 0x20, 0x24, 0x28, 0x2C)
CCR = (0x34, 0x38, 0x3C, 0x40)


class GeneralTimer(RegisterFile):
    size = 0x400
    IRQ_LINE = 0
    RESET: ClassVar[dict[int, int]] = {
        CR1: 0, CR2: 0, SMCR: 0, DIER: 0, SR: 0, EGR: 0, CCMR1: 0, CCMR2: 0, CCER: 0, CNT: 0, PSC: 0,
        ARR: 0xFFFF_FFFF, **dict.fromkeys(CCR, 0), 0x48: 0, 0x5C: 0, 0x60: 0, 0x64: 0, 0x68: 0, 0x3DC: 0, 0x3E0: 0}

    def reset(self) -> None:
        super().reset()
        self.anchor = 0  # cycle (plain mode) or encoder edges (encoder mode) at which CNT was `anchor_cnt`
        self.anchor_cnt = 0
        self.last_edges = 0
        self.down = False
        self._enc = 0

    @property
    def encoder_mode(self) -> int:
        """SMCR.SMS when it is an encoder mode (1-3), else 0 (kept from the last SMCR write)."""
        return self._enc

    def _set_encoder_mode(self) -> None:
        sms = self.regs[SMCR] & 7 | (self.regs[SMCR] >> 16 & 1) << 3
        self._enc = sms if sms in (1, 2, 3) else 0

    @property
    def running(self) -> bool:
        return bool(self.regs[CR1] & 1)

    def _modulus(self) -> int:
        return (self.regs[ARR] & 0xFFFF) + 1

    def counter(self, now: int) -> int:
        if self.encoder_mode:
            edges = services(self.bus).encoder_position(self.name, now)
            if edges != self.last_edges:
                self.down = edges < self.last_edges
                self.last_edges = edges
            counts = edges if self.encoder_mode == 3 else edges // 2
            if not self.running:
                return self.anchor_cnt
            return (self.anchor_cnt + counts - self.anchor) % self._modulus()
        if not self.running:
            return self.anchor_cnt
        ticks = (now - self.anchor) // (self.regs[PSC] + 1)
        return (self.anchor_cnt + ticks) % self._modulus()

    def _counts_now(self, now: int) -> int:
        edges = services(self.bus).encoder_position(self.name, now)
        return edges if self.encoder_mode == 3 else edges // 2

    def next_event(self, now: int) -> int | None:
        if self.encoder_mode or not self.running or not self.regs[DIER] & 1:
            return None
        period = self._modulus() * (self.regs[PSC] + 1)
        first = self.anchor + (self._modulus() - self.anchor_cnt) * (self.regs[PSC] + 1)
        if now < first:
            return first
        return first + ((now - first) // period + 1) * period

    def advance(self, now: int) -> None:
        if self.encoder_mode or not self.running:
            return
        first = self.anchor + (self._modulus() - self.anchor_cnt) * (self.regs[PSC] + 1)
        if now >= first:
            period = self._modulus() * (self.regs[PSC] + 1)
            wraps = 1 + (now - first) // period
            self.anchor, self.anchor_cnt = first + (wraps - 1) * period, 0
            self.regs[SR] |= 1
            self._irq()

    def _irq(self) -> None:
        if self.regs[SR] & self.regs[DIER] & 1:
            self.bus.set_pending(self.IRQ_LINE)
        else:
            self.bus.clear_pending(self.IRQ_LINE)

    def load(self, word: int, now: int) -> int:
        if word == CNT:
            self.advance(now)
            return self.counter(now)
        if word == CR1:
            self.counter(now)
            return self.regs[CR1] & ~0x10 | (0x10 if self.down else 0)
        if word == SR:
            self.advance(now)
        if word == EGR:
            return 0
        return self.regs[word]

    def _rebase(self, now: int, cnt: int) -> None:
        self.anchor_cnt = cnt % self._modulus()
        self.anchor = self._counts_now(now) if self.encoder_mode else now

    def store(self, word: int, value: int, now: int) -> None:
        self.advance(now)
        if word == SR:
            self.regs[SR] &= value
            self._irq()
            return
        if word == CNT:
            self._rebase(now, value)
            return
        if word == EGR:
            if value & 1:
                self._rebase(now, 0)
                self.regs[SR] |= 1
                self._irq()
            return
        if word == CR1:
            if value & 8:
                raise BoardError(f"{self.name}.CR1.OPM: one-pulse mode is not modelled")
            cnt = self.counter(now)
            self.regs[CR1] = value
            self._rebase(now, cnt)
            return
        if word == SMCR:
            sms = value & 7 | (value >> 16 & 1) << 3
            if sms and sms not in (1, 2, 3):
                raise BoardError(f"{self.name}.SMCR.SMS = {sms}: only the encoder modes 1-3 are modelled")
            cnt = self.counter(now)
            self.regs[SMCR] = value
            self._set_encoder_mode()
            self._rebase(now, cnt)
            return
        if word == DIER:
            self.regs[DIER] = value
            self._irq()
            return
        self.regs[word] = value


@register("TIM3")
class Tim3(GeneralTimer):
    base = 0x4000_0400
    IRQ_LINE = IRQ["TIM3"]


@register("TIM4")
class Tim4(GeneralTimer):
    base = 0x4000_0800
    IRQ_LINE = IRQ["TIM4"]
