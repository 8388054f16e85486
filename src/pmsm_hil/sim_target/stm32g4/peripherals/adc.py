"""ADC1 and ADC2 with their common registers (RM0440 chapter 21), as a drive's current and voltage sensing uses
them: the voltage regulator and deep power-down bits, calibration (ADCAL clears after its time), ADEN/ADRDY and
ADDIS, injected sequences (JSQR: 1-4 channels, JEXTSEL/JEXTEN triggers, JADSTART/JADSTP, JDR1-4) and regular
sequences (SQR1-4, EXTSEL/EXTEN, single and continuous, DR), sampling times (SMPR1/2), 12-bit right or left
alignment, JEOC/JEOS/EOC/EOS/EOSMP/OVR flags and their interrupts on the shared ADC1_2 line.

A conversion samples the board's analog input (`BoardBus.analog_voltage`) at the end of its sampling time and
is ready 12.5 ADC clocks later. External triggers come from TIM1 (TRGO, TRGO2, CC4 for injected; TRGO, TRGO2,
CC1-3 for regular); a trigger from another timer is refused naming it. With CFGR.DMAEN each regular conversion's
end raises the ADC's DMA request (DMAMUX1 input 5 for ADC1, 36 for ADC2), whose channel reads DR (a read of DR
clears EOC); an internal channel an OPAMP drives converts the amplifier's gain times its input (the board's
analog front end names the input `OPAMPn_VINPk` / `OPAMPn_VINM0`, channel 0). Not modelled: oversampling,
offsets, the analog watchdogs' thresholds, differential mode, the injected queue beyond one context, dual mode.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from pmsm_hil.sim_target.stm32g4 import periph_native
from pmsm_hil.sim_target.stm32g4.part import IRQ
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardBus, BoardError, register, services
from pmsm_hil.sim_target.stm32g4.peripherals.opamp import ADC_CHANNELS, Opamp
from pmsm_hil.sim_target.stm32g4.peripherals.regs import RegisterFile

ISR, IER, CR, CFGR, CFGR2, SMPR1, SMPR2 = 0x00, 0x04, 0x08, 0x0C, 0x10, 0x14, 0x18
TR1, TR2, TR3, SQR1, SQR2, SQR3, SQR4, DR, JSQR = 0x20, 0x24, 0x28, 0x30, 0x34, 0x38, 0x3C, 0x40, 0x4C
OFR, JDR, AWD2CR, AWD3CR, DIFSEL, CALFACT, GCOMP = 0x60, 0x80, 0xA0, 0xA4, 0xB0, 0xB4, 0xC0
ADRDY, EOSMP, EOC, EOS, OVR, JEOC, JEOS = 1, 2, 4, 8, 16, 32, 64
ADEN, ADDIS, ADSTART, JADSTART, ADSTP, JADSTP = 1, 2, 4, 8, 16, 32
ADVREGEN, DEEPPWD, ADCAL = 1 << 28, 1 << 29, 1 << 31
DMAEN = 1
#: the internal channels an OPAMP output can drive (opamp.ADC_CHANNELS)
OPAMP_OUTPUTS = frozenset(ADC_CHANNELS)
SAMPLE_CLOCKS = (2.5, 6.5, 12.5, 24.5, 47.5, 92.5, 247.5, 640.5)
CONVERT_CLOCKS = 12.5
CALIBRATION_CLOCKS = 116
READY_CLOCKS = 4
#: ADC12 trigger maps (RM0440 tables 163 and 164): JEXTSEL / EXTSEL code -> TIM1 signal
INJECTED_TRIGGERS = {0: "TRGO", 1: "CC4", 8: "TRGO2"}
REGULAR_TRIGGERS = {0: "CC1", 1: "CC2", 2: "CC3", 9: "TRGO", 10: "TRGO2"}
ADC1_2_IRQ = IRQ["ADC1_2"]
_ASYNC_PRESC = (1, 2, 4, 6, 8, 10, 12, 16, 32, 64, 128, 256)


@dataclass(slots=True)
class Conversion:
    """One conversion under way: its group, rank, channel, sampling instant and end [cycles]."""

    injected: bool
    rank: int
    channel: int
    sample_at: int
    done_at: int
    last: bool


class Adc(RegisterFile):
    """One ADC of the ADC12 pair."""

    size = 0x100
    dma_request = 0  # its DMAMUX request input
    #: advanced with TIM1, whose triggers start its conversions (tim1.Tim1.EVENT_GROUP)
    EVENT_GROUP: ClassVar[str] = "TIM1"
    RESET: ClassVar[dict[int, int]] = {
        ISR: 0, IER: 0, CR: DEEPPWD, CFGR: 0x8000_0000, CFGR2: 0, SMPR1: 0, SMPR2: 0, TR1: 0x0FFF_0000,
        TR2: 0x00FF_0000, TR3: 0x00FF_0000, SQR1: 0, SQR2: 0, SQR3: 0, SQR4: 0, DR: 0, JSQR: 0,
        **dict.fromkeys(range(OFR, OFR + 16, 4), 0), **dict.fromkeys(range(JDR, JDR + 16, 4), 0), AWD2CR: 0,
        AWD3CR: 0, DIFSEL: 0, CALFACT: 0, GCOMP: 0}
    #: a model in C (adc_native)
    IS_NATIVE: ClassVar[bool] = False

    def __new__(cls, bus: BoardBus) -> Adc:
        """ADC1 and ADC2 in C (adc_native) while periph_native.NATIVE is set, else this reference."""
        del bus
        if periph_native.NATIVE and not cls.IS_NATIVE and cls.name in ("ADC1", "ADC2"):
            from pmsm_hil.sim_target.stm32g4.peripherals.adc_native import NATIVE_CLASSES
            cls = NATIVE_CLASSES[cls.name]
        return super().__new__(cls)

    def reset(self) -> None:
        super().reset()
        self.cal_done_at: int | None = None
        self.ready_at: int | None = None
        self.ready = False  # enabled and settled (ADRDY was set; software clearing the flag keeps the ADC ready)
        self.queue: list[Conversion] = []
        self.sample_log: list[tuple[int, int, int]] = []  # (cycle, channel, code) of injected samples, recent
        self.triggers = 0
        self._subscribed: tuple[str, ...] = ()
        self._common_model: Adc12Common | None = None  # ADC12_COMMON, looked up on first use

    @property
    def _common(self) -> Adc12Common:
        """The pair's common registers (ADC12_COMMON: the clock, the shared interrupt line)."""
        common = self._common_model
        if common is None:
            found = self.bus.peripheral("ADC12_COMMON")
            assert isinstance(found, Adc12Common)
            common = self._common_model = found
        return common

    # --- clocks ---------------------------------------------------------------------------------------------------

    def cycles_per_adc_clock(self) -> float:
        """HCLK cycles per ADC clock: CKMODE 1-3 (HCLK/1, /2, /4), else the async clock (SYSCLK or PLLP / PRESC,
        taken as HCLK / PRESC)."""
        ccr = self._common.regs[0x08]
        ckmode = ccr >> 16 & 3
        if ckmode:
            return float((1, 1, 2, 4)[ckmode])
        presc = ccr >> 18 & 0xF
        return float(_ASYNC_PRESC[presc] if presc < len(_ASYNC_PRESC) else 256)

    def _sample_clocks(self, channel: int) -> float:
        reg, field = (SMPR1, channel) if channel < 10 else (SMPR2, channel - 10)
        return SAMPLE_CLOCKS[self.regs[reg] >> (3 * field) & 7]

    # --- events ---------------------------------------------------------------------------------------------------

    def next_event(self, now: int) -> int | None:
        best = self.queue[0].done_at if self.queue else None
        for at in (self.cal_done_at, self.ready_at):
            if at is not None and (best is None or at < best):
                best = at
        return best

    def advance(self, now: int) -> None:
        if self.cal_done_at is not None and now >= self.cal_done_at:
            self.cal_done_at = None
            self.regs[CR] &= ~ADCAL
            self.regs[CALFACT] = 0x0041_0041
        if self.ready_at is not None and now >= self.ready_at:
            self.ready_at = None
            self.ready = True
            self._set(ADRDY)
        while self.queue and self.queue[0].done_at <= now:
            self._finish(self.queue.pop(0))

    def _finish(self, conv: Conversion) -> None:
        code = self._code(conv.channel, conv.sample_at)
        if conv.injected:
            self.regs[JDR + 4 * conv.rank] = code
            self.sample_log.append((conv.sample_at, conv.channel, code))
            del self.sample_log[:-64]
            flags = JEOC | (JEOS if conv.last else 0)
            if conv.last and not (self.regs[JSQR] >> 7 & 3):
                self.regs[CR] &= ~JADSTART  # software-triggered sequence done
        else:
            if self.regs[ISR] & EOC and not self.regs[CFGR] >> 12 & 1:
                self._set(OVR)
            self.regs[DR] = code
            flags = EOC | (EOS if conv.last else 0)
            if conv.last and not (self.regs[CFGR] >> 10 & 3) and not (self.regs[CFGR] >> 13 & 1):
                self.regs[CR] &= ~ADSTART
            elif conv.last and self.regs[CFGR] >> 13 & 1 and self.regs[CR] & ADSTART:
                self._start_regular(conv.done_at)
        self._set(flags | EOSMP)
        if not conv.injected and self.regs[CFGR] & DMAEN:  # the DMA request: its channel reads DR, clearing EOC
            self.bus.peripheral("DMAMUX1").request(self.dma_request, conv.done_at)  # type: ignore[attr-defined]

    def _code(self, channel: int, at: int) -> int:
        board = services(self.bus)
        volts = board.analog_voltage(self.name, channel, at)
        opamp = self._opamp() if (self.name, channel) in OPAMP_OUTPUTS else None
        if opamp is not None:
            path = opamp.gain_and_source(self.name, channel)
            if path is not None:  # an internal amplifier's output: gain times its input (and the inverting path)
                gain, source = path
                volts = gain * board.analog_voltage(source, 0, at)
                inverting = opamp.inverting_path(self.name, channel)
                if inverting is not None:
                    volts += inverting[0] * board.analog_voltage(inverting[1], 0, at)
        vref = board.analog_voltage(self.name, -1, at)
        res = self.regs[CFGR] >> 3 & 3
        bits = (12, 10, 8, 6)[res]
        full = (1 << bits) - 1
        code = min(max(round(volts / vref * full), 0), full)
        if self.regs[CFGR] >> 15 & 1:  # ALIGN left
            code <<= 16 - bits if bits > 6 else 8 - bits
        return code

    def _opamp(self) -> Opamp | None:
        """The board's OPAMP model (None on a board without one)."""
        try:
            opamp = self.bus.peripheral("OPAMP")
        except (BoardError, KeyError):
            return None
        return opamp if isinstance(opamp, Opamp) else None

    def _set(self, bits: int) -> None:
        self.regs[ISR] |= bits
        self._common.line_changed()

    def irq_asserted(self) -> bool:
        return bool(self.regs[ISR] & self.regs[IER] & 0x7FF)

    # --- conversions ----------------------------------------------------------------------------------------------

    def _sequence(self, injected: bool) -> list[int]:
        if injected:
            jsqr = self.regs[JSQR]
            n = (jsqr & 3) + 1
            return [jsqr >> (9 + 6 * i) & 0x1F for i in range(n)]
        n = (self.regs[SQR1] & 0xF) + 1
        out = []
        for rank in range(n):
            pos = rank + 1  # SQ1 is in SQR1 bits 6..10
            reg = SQR1 + 4 * (pos // 5)
            out.append(self.regs[reg] >> (6 * (pos % 5)) & 0x1F)
        return out

    def _start(self, injected: bool, at: int) -> None:
        if not self.ready or not self.regs[CR] & ADEN:
            return
        per_clock = self.cycles_per_adc_clock()
        t = float(at) if not self.queue else float(self.queue[-1].done_at)
        channels = self._sequence(injected)
        if injected:
            self.queue = [c for c in self.queue if c.injected is False]  # injected preempts a regular sequence
            t = float(at)
        for rank, ch in enumerate(channels):
            sample = t + self._sample_clocks(ch) * per_clock
            done = sample + CONVERT_CLOCKS * per_clock
            self.queue.append(Conversion(injected, rank, ch, round(sample), round(done), rank == len(channels) - 1))
            t = done
        self.queue.sort(key=lambda c: c.done_at)

    def _start_regular(self, at: int) -> None:
        self._start(False, at)

    def on_trigger(self, signal: str, rising: bool, at: int) -> None:
        """An edge of a TIM1 signal this ADC subscribed to."""
        cr = self.regs[CR]
        for injected, start_bit, edge_field, table in ((True, JADSTART, self.regs[JSQR] >> 7 & 3, INJECTED_TRIGGERS),
                                                        (False, ADSTART, self.regs[CFGR] >> 10 & 3, REGULAR_TRIGGERS)):
            if not cr & start_bit or not edge_field:
                continue
            sel = (self.regs[JSQR] >> 2 & 0x1F) if injected else (self.regs[CFGR] >> 5 & 0x1F)
            if table.get(sel) != signal:
                continue
            if (edge_field == 1 and rising) or (edge_field == 2 and not rising) or edge_field == 3:
                if injected:
                    self.triggers += 1
                self._start(injected, at)

    def _subscribe(self) -> None:
        """Listen to the TIM1 signals the current JSQR/CFGR select (when their triggers are enabled)."""
        wanted = []
        for edge, sel, table, what in ((self.regs[JSQR] >> 7 & 3, self.regs[JSQR] >> 2 & 0x1F, INJECTED_TRIGGERS,
                                        "JSQR.JEXTSEL"),
                                       (self.regs[CFGR] >> 10 & 3, self.regs[CFGR] >> 5 & 0x1F, REGULAR_TRIGGERS,
                                        "CFGR.EXTSEL")):
            if not edge:
                continue
            if sel not in table:
                raise BoardError(f"{self.name}.{what} = {sel}: only the TIM1 triggers are modelled "
                                 f"({', '.join(f'{k}: TIM1_{v}' for k, v in sorted(table.items()))})")
            wanted.append(table[sel])
        tim1 = self.bus.peripheral("TIM1")
        if tuple(wanted) != self._subscribed:
            tim1.unsubscribe(self.on_trigger)  # type: ignore[attr-defined]
            for signal in wanted:
                tim1.subscribe(signal, self.on_trigger)  # type: ignore[attr-defined]
            self._subscribed = tuple(wanted)

    # --- registers ------------------------------------------------------------------------------------------------

    def read(self, offset: int, size: int, now: int) -> int:
        if size == 4 and offset in self.regs:  # an aligned word (the register file's own path, one call fewer)
            return self.load(offset, now)
        return super().read(offset, size, now)

    def load(self, word: int, now: int) -> int:
        self.advance(now)
        if word == DR and self.regs[ISR] & EOC:  # reading the data clears EOC
            self.regs[ISR] &= ~EOC
            self._common.line_changed()
        return self.regs[word]

    def store(self, word: int, value: int, now: int) -> None:
        self.advance(now)
        if word == ISR:  # write 1 to clear
            self.regs[ISR] &= ~value
            self._common.line_changed()
            return
        if word == IER:
            self.regs[IER] = value & 0x7FF
            self._common.line_changed()
            return
        if word == CR:
            self._control(value, now)
            return
        if word in (JDR, JDR + 4, JDR + 8, JDR + 12, DR):
            return
        self.regs[word] = value
        if word in (JSQR, CFGR):
            self._subscribe()

    def _control(self, value: int, now: int) -> None:
        cr = self.regs[CR]
        per_clock = self.cycles_per_adc_clock()
        keep = cr & (ADCAL | ADSTART | JADSTART | ADEN)
        new = (value & (ADVREGEN | DEEPPWD | (1 << 30))) | keep
        if value & ADCAL and not cr & ADCAL:
            if cr & ADEN:
                raise BoardError(f"{self.name}.CR.ADCAL set while ADEN = 1 (RM0440 21.4.8: calibrate disabled)")
            if not value & ADVREGEN or value & DEEPPWD:
                raise BoardError(f"{self.name}.CR.ADCAL: the voltage regulator is off (ADVREGEN = 0 or DEEPPWD = 1)")
            new |= ADCAL
            self.cal_done_at = now + round(CALIBRATION_CLOCKS * per_clock)
        if value & ADEN and not cr & ADEN:
            new |= ADEN
            self.ready_at = now + round(READY_CLOCKS * per_clock)
        if value & ADDIS and cr & ADEN:
            new &= ~(ADEN | ADSTART | JADSTART)
            self.regs[ISR] &= ~ADRDY
            self.ready = False
            self.ready_at = None
            self.queue.clear()
        if value & JADSTP:
            new &= ~JADSTART
            self.queue = [c for c in self.queue if not c.injected]
        if value & ADSTP:
            new &= ~ADSTART
            self.queue = [c for c in self.queue if c.injected]
        self.regs[CR] = new
        if value & JADSTART and new & ADEN:
            self.regs[CR] |= JADSTART
            if not self.regs[JSQR] >> 7 & 3:
                self._start(True, now)
        if value & ADSTART and new & ADEN:
            self.regs[CR] |= ADSTART
            if not self.regs[CFGR] >> 10 & 3:
                self._start(False, now)


@register("ADC1")
class Adc1(Adc):
    base = 0x5000_0000
    dma_request = 5  # DMAMUX input (RM0440 table 91)


@register("ADC2")
class Adc2(Adc):
    base = 0x5000_0100
    dma_request = 36


@register("ADC12_COMMON")
class Adc12Common(RegisterFile):
    """CSR (the two ADCs' flags, read-only), CCR (clock mode, prescaler, internal channels), CDR."""

    base = 0x5000_0300
    size = 0x100
    #: its accesses reach ADC1 and ADC2 (tim1.Tim1.EVENT_GROUP)
    EVENT_GROUP: ClassVar[str] = "TIM1"
    RESET: ClassVar[dict[int, int]] = {0x00: 0, 0x08: 0, 0x0C: 0}

    def reset(self) -> None:
        super().reset()
        self._pair: tuple[Adc, Adc] | None = None  # ADC1 and ADC2, looked up on first use
        self._line_on = False  # ADC1_2 asserted by the pair
        self._sync_clock()

    def _sync_clock(self) -> None:
        """CCR to the ADCs' C state (their clock) when they run in C."""
        if periph_native.NATIVE:
            from pmsm_hil.sim_target.stm32g4.peripherals.adc_native import pair_of
            pair_of(self.bus).state.common_ccr = self.regs[0x08]

    def load(self, word: int, now: int) -> int:
        if word == 0x00:
            adc1, adc2 = self.bus.peripheral("ADC1"), self.bus.peripheral("ADC2")
            return (adc1.read(ISR, 4, now) & 0x7FF) | (adc2.read(ISR, 4, now) & 0x7FF) << 16
        if word == 0x0C:
            adc1, adc2 = self.bus.peripheral("ADC1"), self.bus.peripheral("ADC2")
            return adc1.read(DR, 4, now) | adc2.read(DR, 4, now) << 16
        return self.regs[word]

    def store(self, word: int, value: int, now: int) -> None:
        if word == 0x08:
            if value & 0x1F:
                raise BoardError("ADC12_COMMON.CCR.DUAL: dual ADC modes are not modelled")
            self.regs[0x08] = value
            self._sync_clock()
        elif word != 0x00 and word != 0x0C:
            self.regs[word] = value

    def line_changed(self) -> None:
        """ADC1_2 is asserted while either ADC has an enabled flag set (pending it again), withdrawn when that
        ends."""
        if self._pair is None:
            adc1, adc2 = self.bus.peripheral("ADC1"), self.bus.peripheral("ADC2")
            assert isinstance(adc1, Adc) and isinstance(adc2, Adc)
            self._pair = (adc1, adc2)
        adc1, adc2 = self._pair
        if adc1.irq_asserted() or adc2.irq_asserted():
            self._line_on = True
            self.bus.set_pending(ADC1_2_IRQ)
        elif self._line_on:
            self._line_on = False
            self.bus.clear_pending(ADC1_2_IRQ)
