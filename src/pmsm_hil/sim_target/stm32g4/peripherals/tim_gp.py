"""TIM3 and TIM4, general-purpose timers (RM0440 chapter 29), as a drive uses them: encoder mode (SMCR.SMS 1, 2
or 3: x2 on TI1 or TI2, x4 on both) counting the board's encoder (`BoardBus.encoder_position`) modulo ARR + 1,
with DIR following the rotation, and otherwise a plain up-counter at the timer clock through PSC with the update
interrupt (UIF/UIE) for a time base; and the hall-sensor interface on a board whose hall sensors feed the timer
(`hall_inputs`): CR2.TI1S puts the XOR of the three hall inputs on TI1, reset mode (SMCR.SMS 100) triggered by
TI1F_ED (SMCR.TS 00100) captures CNT into CCR1 (CCMR1.CC1S 11, TRC; CC1IF, CC1OF) and restarts the counter at each
hall edge (TIF, and UIF unless CR1.URS), with their interrupts (CC1IE, TIE, UIE). Other capture/compare uses, other
slave modes, DMA and one-pulse mode are not modelled (a write enabling one is refused naming the field). TIM3's page
is served by c/tim_gp.c, which answers a CNT read in C while the timer counts the board link's encoder (`arm_encoder`,
`sync_encoder`; `NATIVE_ENCODER`) and hands every other access to this model."""

from __future__ import annotations

import ctypes
from typing import Any, ClassVar, Protocol

from pmsm_hil.sim_target.stm32g4 import periph_native as pn
from pmsm_hil.sim_target.stm32g4.counter import CounterState
from pmsm_hil.sim_target.stm32g4.part import IRQ
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError, register, services
from pmsm_hil.sim_target.stm32g4.peripherals.regs import RegisterFile

CR1, CR2, SMCR, DIER, SR, EGR, CCMR1, CCMR2, CCER, CNT, PSC, ARR = (
    0x00, 0x04, 0x08, 0x0C, 0x10, 0x14, 0x18, 0x1C, 0x20, 0x24, 0x28, 0x2C)
CCR = (0x34, 0x38, 0x3C, 0x40)
UIF, CC1IF, TIF, CC1OF = 1, 1 << 1, 1 << 6, 1 << 9
#: SMCR.SMS = reset mode, SMCR.TS = TI1F_ED (the TI1 edge detector): the hall interface's trigger
SMS_RESET, TS_TI1F_ED = 4, 4
#: TIM3's CNT read in C while it counts the board link's encoder (c/tim_gp.c; False: every access through the Python
#: model, which gives the same records)
NATIVE_ENCODER = True
#: counts and anchors the C read takes (beyond: Python's integers)
_C_LIMIT = 1 << 61


class TimGpState(ctypes.Structure):
    """Mirror of hil_tim_gp_t (c/tim_gp.c)."""

    _fields_ = [("armed", ctypes.c_int32), ("enc", ctypes.c_int32), ("running", ctypes.c_int32),
                ("down", ctypes.c_int32), ("anchor", ctypes.c_int64), ("anchor_cnt", ctypes.c_int64),
                ("modulus", ctypes.c_int64), ("last_edges", ctypes.c_int64), ("cnt_offset", ctypes.c_uint32),
                ("pad", ctypes.c_int32), ("theta_m", ctypes.c_double), ("omega_m", ctypes.c_double),
                ("period_start", ctypes.c_int64), ("hclk_hz", ctypes.c_double), ("lines", ctypes.c_double),
                ("count", ctypes.c_void_p), ("fallback_read", ctypes.c_void_p), ("fallback_write", ctypes.c_void_p),
                ("fallback_user", ctypes.c_void_p)]


class HallInput(Protocol):
    """The hall sensors wired to a timer's CH1-CH3."""

    def code(self, now: int) -> int:
        """The three inputs' levels at cycle `now` (A | B << 1 | C << 2)."""

    def next_edge(self, now: int) -> int | None:
        """The first cycle after `now` at which one of them changes (None: none due)."""


class GeneralTimer(RegisterFile):
    size = 0x400
    IRQ_LINE = 0
    RESET: ClassVar[dict[int, int]] = {
        CR1: 0, CR2: 0, SMCR: 0, DIER: 0, SR: 0, EGR: 0, CCMR1: 0, CCMR2: 0, CCER: 0, CNT: 0, PSC: 0,
        ARR: 0xFFFF_FFFF, **dict.fromkeys(CCR, 0), 0x48: 0, 0x5C: 0, 0x60: 0, 0x64: 0, 0x68: 0, 0x3DC: 0, 0x3E0: 0}

    def reset(self) -> None:
        super().reset()
        #: the C read's state (c/tim_gp.c) once the board maps the page to it (`map_native`), else None
        self._c: TimGpState | None = getattr(self, "_c", None)
        self._encoder_lines: int | None = getattr(self, "_encoder_lines", None)
        self.anchor = 0  # cycle (plain mode) or encoder edges (encoder mode) at which CNT was `anchor_cnt`
        self.anchor_cnt = 0
        self._last_edges = 0
        self._down = False
        self._enc = 0
        if self._c is not None:
            self._c.last_edges, self._c.down = 0, 0
            self._push()
        #: the hall sensors on CH1-CH3 (the board's, when its description wires them to this timer)
        self.hall_inputs: HallInput | None = getattr(self, "hall_inputs", None)
        self._hall_code = 0
        #: hall edges the interface took (captures)
        self.hall_captures = 0

    @property
    def last_edges(self) -> int:
        """The encoder's edge count at the last read of the counter (in the C read's struct while it has one)."""
        c = self._c
        return self._last_edges if c is None else int(c.last_edges)

    @last_edges.setter
    def last_edges(self, value: int) -> None:
        c = self._c
        if c is not None and -_C_LIMIT < value < _C_LIMIT:
            c.last_edges = value
            return
        if c is not None:
            self._detach()
        self._last_edges = value

    @property
    def down(self) -> bool:
        """The direction of the last change of the encoder's edge count (CR1.DIR)."""
        c = self._c
        return self._down if c is None else bool(c.down)

    @down.setter
    def down(self, value: bool) -> None:
        c = self._c
        if c is not None:
            c.down = int(value)
        else:
            self._down = value

    def _hall_mode(self) -> bool:
        smcr = self.regs[SMCR]
        sms = smcr & 7 | (smcr >> 16 & 1) << 3
        ts = smcr >> 4 & 7 | (smcr >> 20 & 3) << 3
        return self.hall_inputs is not None and sms == SMS_RESET and ts == TS_TI1F_ED and bool(self.regs[CR2] & 0x80)

    def quiet(self) -> bool:
        """Neither `advance` nor `next_event` does anything until an access changes the configuration (an encoder
        or a stopped counter without hall sensors): the board need not call them meanwhile."""
        return self.hall_inputs is None and (bool(self._enc) or not self.regs[CR1] & 1)

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
        edge = None
        if self.hall_inputs is not None and self._hall_mode() and self.running:
            if self.hall_inputs.code(now) != self._hall_code:
                return now
            edge = self.hall_inputs.next_edge(now)
        wrap = self._next_wrap(now)
        return wrap if edge is None else edge if wrap is None else min(edge, wrap)

    def _next_wrap(self, now: int) -> int | None:
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
        self._wraps(now)
        if self.hall_inputs is not None and self._hall_mode():
            code = self.hall_inputs.code(now)
            if code != self._hall_code:
                self._hall_code = code
                self._hall_edge(now)

    def _hall_edge(self, now: int) -> None:
        """A hall edge at cycle `now`: CNT captured into CCR1 (CC1S = TRC with CC1E), the counter restarted."""
        ccmr1, ccer = self.regs[CCMR1], self.regs[CCER]
        sr = self.regs[SR] | TIF
        if ccmr1 & 3 == 3 and ccer & 1:
            self.regs[CCR[0]] = self.counter(now)
            sr |= CC1OF if sr & CC1IF else CC1IF
        if not self.regs[CR1] & 4:  # URS clear: the reset is an update event
            sr |= UIF
        self.regs[SR] = sr
        self.hall_captures += 1
        self._rebase(now, 0)
        self._irq()

    def _wraps(self, now: int) -> None:
        first = self.anchor + (self._modulus() - self.anchor_cnt) * (self.regs[PSC] + 1)
        if now >= first:
            period = self._modulus() * (self.regs[PSC] + 1)
            wraps = 1 + (now - first) // period
            self.anchor, self.anchor_cnt = first + (wraps - 1) * period, 0
            self.regs[SR] |= 1
            self._irq()

    def _irq(self) -> None:
        if self.regs[SR] & self.regs[DIER] & (UIF | CC1IF | TIF):
            self.bus.set_pending(self.IRQ_LINE)
        else:
            self.bus.clear_pending(self.IRQ_LINE)

    def read(self, offset: int, size: int, now: int) -> int:
        if size == 4 and offset in self.regs:  # an aligned word (the register file's own path, one call fewer)
            return self.load(offset, now)
        return super().read(offset, size, now)

    def load(self, word: int, now: int) -> int:
        if word == CNT:
            if not self._enc:  # an encoder's count has no events of its own (`advance` does nothing then)
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
        try:
            self._store(word, value, now)
        finally:  # what the store changed, also when it raised half-way
            if self._c is not None:
                self._push()

    def _store(self, word: int, value: int, now: int) -> None:
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
            ts = value >> 4 & 7 | (value >> 20 & 3) << 3
            hall = sms == SMS_RESET and ts == TS_TI1F_ED
            if sms and sms not in (1, 2, 3) and not hall:
                raise BoardError(f"{self.name}.SMCR.SMS = {sms}: only the encoder modes 1-3 and the hall interface "
                                 "(reset mode 100 triggered by TI1F_ED, TS 00100, with CR2.TI1S) are modelled")
            if hall and self.hall_inputs is None:
                raise BoardError(f"{self.name}.SMCR: reset mode on TI1F_ED (the hall interface), but the board "
                                 f"description wires no hall sensors to {self.name} ([hall] timer)")
            cnt = self.counter(now)
            self.regs[SMCR] = value
            self._set_encoder_mode()
            self._rebase(now, cnt)
            if self.hall_inputs is not None:
                self._hall_code = self.hall_inputs.code(now)
            return
        if word == DIER:
            self.regs[DIER] = value
            self._irq()
            return
        self.regs[word] = value
        if word == CR2 and self.hall_inputs is not None:
            self._hall_code = self.hall_inputs.code(now)


    # --- the encoder's CNT read in C (c/tim_gp.c) ---------------------------------------------------------------

    #: the page whose MMIO callbacks are the library's (None: the board's decoder serves it)
    _page: ClassVar[int | None] = None

    @property
    def native_page(self) -> int | None:
        """The 4 KiB page the board maps to `map_native` (None: the Python model through the board's decoder)."""
        return self._page if NATIVE_ENCODER else None

    def map_native(self, cpu: Any, read: Any, write: Any) -> None:
        """Serve this timer's page from c/tim_gp.c on `cpu` (`read`/`write`: the board's decoder, for every access
        but an armed encoder's CNT read)."""
        lib = _typed(pn.library("tim_gp"))
        page = self._page or 0
        c = TimGpState()
        c.count = ctypes.addressof(cpu.counter) + CounterState.count.offset
        c.cnt_offset = self.base + CNT - page
        if not -_C_LIMIT < self._last_edges < _C_LIMIT:
            return
        c.last_edges, c.down = self._last_edges, int(self._down)
        self._c = c
        self._push()
        self._keep = pn.map_page(cpu, page, 0x1000, read, write, pn.address(lib.hil_tim_gp_mmio_read),
                                 pn.address(lib.hil_tim_gp_mmio_write), c)
        self._c_state = c  # mapped for good, even after `_detach`

    def arm_encoder(self, lines: int) -> bool:
        """Answer CNT reads in C from the encoder's angle (`sync_encoder`, then once a period) with `lines` lines per
        revolution, as the board link's encoder; False when this timer's page is not served in C."""
        if self._c is None:
            return False
        self._encoder_lines = lines
        self._c.lines = float(lines)
        self._push()
        return True

    def sync_encoder(self, theta_m: float, omega_m: float, period_start: int, hclk_hz: int) -> None:
        """The board link's encoder: the unwrapped mechanical angle [rad] at cycle `period_start`, the speed
        [rad/s] and the clock [Hz] (its `_encoder`'s values)."""
        c = self._c
        if c is not None:
            c.theta_m, c.omega_m, c.period_start, c.hclk_hz = theta_m, omega_m, period_start, hclk_hz

    def encoder_state(self) -> TimGpState | None:
        """The C read's struct whose encoder fields (theta_m, omega_m, period_start, hclk_hz) `sync_encoder` sets, for
        a caller that keeps them current and sets only those that changed (None: no C read)."""
        return self._c

    def _push(self) -> None:
        """The model's state after a store into the C read's struct, armed while the encoder is (the C read's state
        given back to Python for good when a count leaves the range it takes: `_detach`)."""
        c = self._c
        assert c is not None
        anchor, anchor_cnt = self.anchor, self.anchor_cnt
        if not (-_C_LIMIT < anchor < _C_LIMIT and -_C_LIMIT < anchor_cnt < _C_LIMIT):
            self._detach()
            return
        c.enc, c.running, c.modulus, c.anchor, c.anchor_cnt = (self._enc, int(self.running), self._modulus(), anchor,
                                                               anchor_cnt)
        c.armed = int(self._encoder_lines is not None)

    def _detach(self) -> None:
        """Every access through Python from now on (the page stays mapped, its C read disarmed)."""
        c = self._c
        assert c is not None
        self._last_edges, self._down = int(c.last_edges), bool(c.down)
        c.armed = 0
        self._c = None


def _typed(lib: ctypes.CDLL) -> ctypes.CDLL:
    if not getattr(lib, "_hil_typed", False):
        lib.hil_tim_gp_size.argtypes, lib.hil_tim_gp_size.restype = [], ctypes.c_uint
        if lib.hil_tim_gp_size() != ctypes.sizeof(TimGpState):
            raise pn.PeriphBuildError("c/tim_gp.c's hil_tim_gp_t and tim_gp.TimGpState differ in size")
        lib._hil_typed = True  # type: ignore[attr-defined]
    return lib


@register("TIM3")
class Tim3(GeneralTimer):
    base = 0x4000_0400
    IRQ_LINE = IRQ["TIM3"]
    #: the page of TIM2-TIM5 (one model can serve it in C: TIM3, the encoder timer of the example board)
    _page = 0x4000_0000


@register("TIM4")
class Tim4(GeneralTimer):
    base = 0x4000_0800
    IRQ_LINE = IRQ["TIM4"]
