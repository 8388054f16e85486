"""OPAMP1..OPAMP6 of the STM32G474 (RM0440 "Operational amplifiers") at 0x40010300: OPAMPx_CSR at 4 * (x - 1),
OPAMPx_TCMR at 0x18 + 4 * (x - 1).

The model answers the ADC's question "what does this internal channel see" (`gain_and_source`, `inverting_path`):
an amplifier with OPAINTOEN set drives its ADC channel (OPAMP1: ADC1 IN13, OPAMP2: ADC2 IN16, OPAMP3: ADC2 IN18 and
ADC3 IN13, OPAMP4: ADC5 IN5, OPAMP5: ADC5 IN3, OPAMP6: ADC4 IN17) with VINPn (VP_SEL) times the PGA gain (VM_SEL
= 10) or once (follower, VM_SEL = 11). The inputs are named as RM0440 names them (`OPAMP1_VINP0`); which pin or DAC
channel drives each is the board description's business. Offset calibration: the trim fields are stored, and
CALOUT, with CALON set, reads 1 while the trim of the pair CALSEL selects (N for 50 %/90 % VDDA, P for 3.3 %/10 %,
as ST's drivers trim N at 90 % and P at 10 %) is below the amplifier's `ideal_trim`, OFFTRIM_S after the last
change, so the drivers' dichotomy search converges.
"""

from __future__ import annotations

from collections.abc import Callable

from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError, Peripheral, register

COUNT = 6
#: parts with OPAMP1..3 only (DS12589: the G431/G441), by name prefix
THREE_AMPLIFIER_PARTS = ("stm32g431", "stm32g441")
TCMR_BASE = 0x18

# CSR fields
OPAEN, FORCE_VP = 1 << 0, 1 << 1
VP_SEL_SHIFT, VM_SEL_SHIFT = 2, 5
USERTRIM, OPAHSM, OPAINTOEN, CALON = 1 << 4, 1 << 7, 1 << 8, 1 << 11
CALSEL_SHIFT, PGA_GAIN_SHIFT, TRIMOFFSETP_SHIFT, TRIMOFFSETN_SHIFT = 12, 14, 19, 24
CALOUT, LOCK = 1 << 30, 1 << 31
CSR_WRITABLE = 0x9FFF_F9FF
TCMR_WRITABLE = 0x8000_003F
TCMR_TIMER_MUX = 0x38  # T1CMEN, T8CMEN, T20CMEN
VM_PGA, VM_FOLLOWER = 0b10, 0b11

#: the offset-trim settling time the model gives CALOUT [s] (drivers wait the datasheet's 2 ms maximum per step)
OFFTRIM_S = 1e-3

#: (ADC, channel) -> the amplifier (1-based) whose internal output it converts (RM0440 ADC connectivity)
ADC_CHANNELS = {("ADC1", 13): 1, ("ADC2", 16): 2, ("ADC2", 18): 3, ("ADC3", 13): 3, ("ADC5", 5): 4,
                ("ADC5", 3): 5, ("ADC4", 17): 6}


@register("OPAMP")
class Opamp(Peripheral):
    """The six amplifiers' CSR and TCMR registers, with their PGA gain and input selection for the ADC model."""

    base = 0x4001_0300
    size = 0x100
    #: called when a CSR is written (the board link's period in C then hands the period to Python), or None
    on_change: Callable[[], None] | None = None

    def reset(self) -> None:
        part = str(getattr(getattr(self.bus, "part", None), "name", "")).lower()
        #: the amplifiers the part has
        self.count = 3 if part.startswith(THREE_AMPLIFIER_PARTS) else COUNT
        self.csr = [0] * COUNT
        self.tcmr = [0] * COUNT
        #: the trim (N, P) at which each amplifier's offset is cancelled (the board's parts; mid-scale by default)
        self.ideal_trim = [(16, 16)] * COUNT
        self._calout = [0] * COUNT
        #: a CALOUT change still settling: (value, the cycle it shows)
        self._settling: list[tuple[int, int] | None] = [None] * COUNT
        #: writes ignored because LOCK was set (count)
        self.ignored_writes = 0

    # ----- registers
    def _index(self, offset: int, access: str) -> tuple[bool, int]:
        """(is TCMR, amplifier index) of a register offset; BoardError for any other."""
        if offset & 3 == 0 and offset < TCMR_BASE + 4 * COUNT and (offset % TCMR_BASE) // 4 < self.count:
            return offset >= TCMR_BASE, (offset % TCMR_BASE) // 4
        raise BoardError(f"{access} of OPAMP at offset {offset:#05x} ({self.base + offset:#010x}), which the virtual "
                         "board does not model (OPAMPx_CSR, OPAMPx_TCMR, word-aligned)")

    def read(self, offset: int, size: int, now: int) -> int:
        del size
        is_tcmr, i = self._index(offset, "read")
        if is_tcmr:
            return self.tcmr[i]
        return self.csr[i] | (CALOUT if self._calout_at(i, now) else 0)

    def write(self, offset: int, size: int, value: int, now: int) -> None:
        del size
        is_tcmr, i = self._index(offset, "write")
        if is_tcmr:
            if self.tcmr[i] & LOCK:
                self.ignored_writes += 1
            elif value & TCMR_TIMER_MUX:
                raise BoardError(f"OPAMP{i + 1}_TCMR: the timer-controlled input multiplexer (T1CMEN/T8CMEN/T20CMEN) "
                                 "is not modelled by the virtual board")
            else:
                self.tcmr[i] = value & TCMR_WRITABLE
            return
        if self.csr[i] & LOCK:
            self.ignored_writes += 1
            return
        self._calout_at(i, now)
        self.csr[i] = value & CSR_WRITABLE
        if self.on_change is not None:
            self.on_change()
        target = self._calout_target(i)
        pending = self._settling[i]
        if target != (pending[0] if pending is not None else self._calout[i]):
            self._settling[i] = (target, now + round(OFFTRIM_S * self.bus.sysclk_hz))

    def _calout_target(self, i: int) -> int:
        """What CALOUT settles to for the present CSR: the calibration comparator's output."""
        csr = self.csr[i]
        if not csr & CALON or not csr & OPAEN:
            return 0
        ideal_n, ideal_p = self.ideal_trim[i]
        if (csr >> CALSEL_SHIFT) & 3 >= 2:
            return int((csr >> TRIMOFFSETN_SHIFT) & 0x1F < ideal_n)
        return int((csr >> TRIMOFFSETP_SHIFT) & 0x1F < ideal_p)

    def _calout_at(self, i: int, now: int) -> int:
        pending = self._settling[i]
        if pending is not None and now >= pending[1]:
            self._calout[i] = pending[0]
            self._settling[i] = None
        return self._calout[i]

    # ----- what the ADC sees
    def _driving(self, adc_name: str, channel: int) -> int | None:
        """The index of the amplifier driving `adc_name`'s `channel`, None when no amplifier does; BoardError when
        its output is routed there but the amplifier cannot be said to amplify (off, calibrating, forced)."""
        number = ADC_CHANNELS.get((adc_name, channel))
        if number is None:
            return None
        i = number - 1
        csr = self.csr[i]
        if not csr & OPAINTOEN:
            return None
        where = f"OPAMP{number} (output to {adc_name} channel {channel})"
        if not csr & OPAEN:
            raise BoardError(f"{where} is converted while OPAEN is clear")
        if csr & (CALON | FORCE_VP):
            raise BoardError(f"{where} is converted in calibration (CALON or FORCE_VP set)")
        return i

    def _pga_gain(self, i: int) -> int:
        """The non-inverting PGA gain (2..64) of amplifier `i`'s PGA_GAIN."""
        exponent = (self.csr[i] >> PGA_GAIN_SHIFT) & 0x7
        if exponent > 5:
            raise BoardError(f"OPAMP{i + 1}_CSR: PGA_GAIN = {(self.csr[i] >> PGA_GAIN_SHIFT) & 0x1F:#07b} is reserved")
        return 2 << exponent

    def gain_and_source(self, adc_name: str, channel: int) -> tuple[float, str] | None:
        """(gain, input) of the amplifier whose output `adc_name`'s internal `channel` converts: the output is
        gain * V(input) (+ the inverting path of `inverting_path`); None when no amplifier output is routed there.
        BoardError for a standalone amplifier (VM_SEL 00/01), whose gain is set by the board's resistors."""
        i = self._driving(adc_name, channel)
        if i is None:
            return None
        csr = self.csr[i]
        vm_sel = (csr >> VM_SEL_SHIFT) & 3
        source = f"OPAMP{i + 1}_VINP{(csr >> VP_SEL_SHIFT) & 3}"
        if vm_sel == VM_FOLLOWER:
            return 1.0, source
        if vm_sel == VM_PGA:
            return float(self._pga_gain(i)), source
        raise BoardError(f"OPAMP{i + 1}_CSR: VM_SEL = {vm_sel:#04b} (standalone, gain set by external resistors) is "
                         "not modelled by the virtual board; use the PGA (10) or follower (11) mode")

    def inverting_path(self, adc_name: str, channel: int) -> tuple[float, str] | None:
        """(gain, input) of the PGA's inverting input when PGA_GAIN[4:3] routes VINM0 as an input (01, 11): the
        output adds -(G - 1) * V(VINM0); None without that path."""
        i = self._driving(adc_name, channel)
        if i is None:
            return None
        csr = self.csr[i]
        if (csr >> VM_SEL_SHIFT) & 3 != VM_PGA or not (csr >> (PGA_GAIN_SHIFT + 3)) & 1:
            return None
        return float(1 - self._pga_gain(i)), f"OPAMP{i + 1}_VINM0"


__all__ = ["ADC_CHANNELS", "OFFTRIM_S", "Opamp"]
