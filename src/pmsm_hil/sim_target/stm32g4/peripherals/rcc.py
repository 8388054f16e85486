"""RCC, PWR and FLASH (RM0440 chapters 7, 6, 5): the clock tree as far as the core clock, every ready flag
following its enable after a settling time (HSIRDY, HSERDY, PLLRDY, LSIRDY, LSERDY, HSI48RDY), SWS following SW once the
source is ready, the PWR regulator flags (VOSF after a range change, R1MODE boost), the FLASH latency read back.
The RCC reports the core clock (HCLK) to the board whenever SW/SWS, the PLL or the AHB prescaler change it, and
names FDCAN's kernel clock (CCIPR.FDCANSEL: HSE, PLL "Q" or PCLK1) with `fdcan_kernel_clock`."""

from __future__ import annotations

from typing import ClassVar

from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError, register, services
from pmsm_hil.sim_target.stm32g4.peripherals.regs import RegisterFile

HSI_HZ = 16_000_000
#: settling times [cycles of the core clock at the moment of the enable]
HSE_SETTLE, PLL_SETTLE, OSC_SETTLE, VOS_SETTLE = 2048, 1024, 256, 64
_HPRE = {8: 2, 9: 4, 10: 8, 11: 16, 12: 64, 13: 128, 14: 256, 15: 512}
_PPRE = {4: 2, 5: 4, 6: 8, 7: 16}


@register("RCC")
class Rcc(RegisterFile):
    base = 0x4002_1000
    size = 0x400
    RESET: ClassVar[dict[int, int]] = {
        0x00: 0x0000_0500, 0x04: 0x4000_0000, 0x08: 0x0000_0005, 0x0C: 0x0000_1000, 0x18: 0, 0x1C: 0,
             0x20: 0, 0x28: 0, 0x2C: 0, 0x30: 0, 0x38: 0, 0x3C: 0, 0x40: 0, 0x48: 0x0000_0100, 0x4C: 0, 0x50: 0,
             0x58: 0, 0x5C: 0, 0x60: 0, 0x68: 0x0000_130F, 0x6C: 0x050F_667F, 0x70: 0x0000_0101,
             0x78: 0xF2FE_CA3F, 0x7C: 0x0000_0103, 0x80: 0x0017_7801, 0x88: 0, 0x90: 0, 0x94: 0x0C00_0000,
             0x98: 0, 0x9C: 0}

    def reset(self) -> None:
        super().reset()
        self.ready_at: dict[str, int | None] = {"HSI": 0, "HSE": None, "PLL": None, "LSI": None, "LSE": None,
                                                "HSI48": None}
        self.sws = 1

    def _ready(self, name: str, now: int) -> bool:
        at = self.ready_at[name]
        return at is not None and now >= at

    def _enable(self, name: str, on: bool, settle: int, now: int) -> None:
        if not on:
            self.ready_at[name] = None
        elif self.ready_at[name] is None:
            self.ready_at[name] = now + settle

    def load(self, word: int, now: int) -> int:
        v = self.regs[word]
        if word == 0x00:
            v &= ~((1 << 10) | (1 << 17) | (1 << 25))
            v |= (1 << 10 if self._ready("HSI", now) else 0) | (1 << 17 if self._ready("HSE", now) else 0) | (
                1 << 25 if self._ready("PLL", now) else 0)
        elif word == 0x08:
            self._switch(now)
            v = (v & ~0xC) | (self.sws << 2)
        elif word == 0x90:
            v = (v & ~2) | (2 if self._ready("LSE", now) else 0)
        elif word == 0x94:
            v = (v & ~2) | (2 if self._ready("LSI", now) else 0)
        elif word == 0x98:
            v = (v & ~2) | (2 if self._ready("HSI48", now) else 0)
        return v

    def store(self, word: int, value: int, now: int) -> None:
        self.regs[word] = value
        if word == 0x00:
            if value >> 24 & 1 and self.sws == 3:
                pass
            elif not value >> 24 & 1 and self.sws == 3:
                raise BoardError("RCC: PLLON cleared while the PLL clocks the core (RM0440 7.4.1)")
            self._enable("HSI", bool(value >> 8 & 1) or self.sws == 1, 16, now)
            self._enable("HSE", bool(value >> 16 & 1), HSE_SETTLE, now)
            self._enable("PLL", bool(value >> 24 & 1), PLL_SETTLE, now)
        elif word == 0x08:
            self._switch(now)
        elif word == 0x0C and self.sws == 3:
            self._report()
        elif word == 0x90:
            self._enable("LSE", bool(value & 1), HSE_SETTLE, now)
        elif word == 0x94:
            self._enable("LSI", bool(value & 1), OSC_SETTLE, now)
        elif word == 0x98:
            self._enable("HSI48", bool(value & 1), OSC_SETTLE, now)
        if word in (0x00, 0x08, 0x0C, 0x88):  # CR, CFGR, PLLCFGR, CCIPR: FDCAN's kernel clock may have changed
            self._fdcan_follows(now)

    def _fdcan_follows(self, now: int) -> None:
        """FDCAN1, when the board has it, follows a change of its kernel clock (`Fdcan.clock_changed`)."""
        try:
            fdcan = self.bus.peripheral("FDCAN1")
        except (BoardError, KeyError):
            return
        follow = getattr(fdcan, "clock_changed", None)
        if follow is not None:
            follow(now)

    def _switch(self, now: int) -> None:
        """SWS follows SW once the selected source is ready; the board hears of the new core clock."""
        sw = self.regs[0x08] & 3
        source = {1: "HSI", 2: "HSE", 3: "PLL"}.get(sw)
        if source is not None and self._ready(source, now) and sw != self.sws:
            self.sws = sw
            self._report()
            self._fdcan_follows(now)  # PCLK1 follows the core clock
            return
        self._report()

    def pll_hz(self) -> int:
        """The PLL's R output (the system clock's PLL source) [Hz]."""
        return self._pll_output(2 * ((self.regs[0x0C] >> 25 & 3) + 1))

    def _pll_output(self, divider: int) -> int:
        """The PLL's VCO (its input through M, times N) through `divider` [Hz]."""
        cfg = self.regs[0x0C]
        src = cfg & 3
        if src == 2:
            f_in = HSI_HZ
        elif src == 3:
            f_in = services(self.bus).hse_hz
        else:
            raise BoardError("RCC: the PLL runs with no source (PLLCFGR.PLLSRC = 0)")
        m, n = (cfg >> 4 & 0xF) + 1, cfg >> 8 & 0x7F
        if not 8 <= n <= 127:
            raise BoardError(f"RCC: PLLN = {n} outside 8..127 (RM0440 7.4.4)")
        return f_in * n // (m * divider)

    def sysclk_hz(self) -> int:
        if self.sws == 2:
            return services(self.bus).hse_hz
        if self.sws == 3:
            return self.pll_hz()
        return HSI_HZ

    def hclk_hz(self) -> int:
        return self.sysclk_hz() // _HPRE.get(self.regs[0x08] >> 4 & 0xF, 1)

    def apb_divider(self, bus: int) -> int:
        """The APB1 (1) or APB2 (2) prescaler."""
        field = self.regs[0x08] >> (8 if bus == 1 else 11) & 7
        return _PPRE.get(field, 1)

    def pclk_hz(self, bus: int) -> int:
        """PCLK1 (bus 1) or PCLK2 (bus 2): HCLK through the APB prescaler [Hz]."""
        return self.hclk_hz() // self.apb_divider(bus)

    def fdcan_kernel_clock(self, now: int) -> tuple[int, str]:
        """FDCAN's kernel clock at cycle `now`: (Hz, what it is); BoardError naming CCIPR.FDCANSEL when the selected
        source is not running (HSE not ready, the PLL's Q output not enabled or the PLL not locked, the reserved
        value 11)."""
        sel = self.regs[0x88] >> 24 & 3
        field = f"RCC CCIPR.FDCANSEL = {sel:02b}"
        if sel == 0:
            if not self._ready("HSE", now):
                raise BoardError(f"{field} (HSE) clocks FDCAN1, but the HSE is not ready (RCC CR.HSEON/HSERDY): "
                                 "FDCAN1 has no kernel clock")
            hz = services(self.bus).hse_hz
            return hz, f"HSE {hz / 1e6:g} MHz"
        if sel == 1:
            cfg = self.regs[0x0C]
            if not cfg >> 20 & 1 or not self._ready("PLL", now):
                raise BoardError(f"{field} (PLL Q) clocks FDCAN1, but the PLL's Q output is not running (RCC "
                                 f"PLLCFGR.PLLQEN {cfg >> 20 & 1}, PLLRDY {int(self._ready('PLL', now))}): FDCAN1 has "
                                 "no kernel clock")
            hz = self._pll_output(2 * ((cfg >> 21 & 3) + 1))
            return hz, f"PLLQ {hz / 1e6:g} MHz"
        if sel == 2:
            hz = self.pclk_hz(1)
            return hz, f"PCLK1 {hz / 1e6:g} MHz"
        raise BoardError(f"{field} is reserved (RM0440 7.4.26): FDCAN1 has no kernel clock")

    def _report(self) -> None:
        hz = self.hclk_hz()
        if hz > 170_000_000:
            raise BoardError(f"RCC: HCLK {hz / 1e6:g} MHz above the part's 170 MHz")
        services(self.bus).set_hclk(hz)


@register("PWR")
class Pwr(RegisterFile):
    base = 0x4000_7000
    size = 0x400
    RESET: ClassVar[dict[int, int]] = {
        0x00: 0x0000_0200, 0x04: 0, 0x08: 0x0000_8000, 0x0C: 0, 0x10: 0, 0x14: 0, 0x18: 0, 0x80: 0x0000_0100,
             **{o: 0 for o in range(0x20, 0x60, 4)}}

    def reset(self) -> None:
        super().reset()
        self.vos_until = 0

    def load(self, word: int, now: int) -> int:
        if word == 0x14:  # SR2: VOSF while the regulator changes range
            return (1 << 10) if now < self.vos_until else 0
        return self.regs[word]

    def store(self, word: int, value: int, now: int) -> None:
        if word == 0x00 and (value ^ self.regs[0]) & 0x600:
            self.vos_until = now + VOS_SETTLE
        if word in (0x10, 0x14, 0x18):
            return  # status, write-1-to-clear
        self.regs[word] = value


@register("FLASH")
class Flash(RegisterFile):
    base = 0x4002_2000
    size = 0x400
    RESET: ClassVar[dict[int, int]] = {
        0x00: 0x0000_0600, 0x04: 0, 0x08: 0, 0x0C: 0, 0x10: 0, 0x14: 0xC000_0000, 0x18: 0, 0x20: 0xFFEF_F8AA,
             0x24: 0, 0x28: 0, 0x2C: 0, 0x30: 0, 0x70: 0}

    def store(self, word: int, value: int, now: int) -> None:
        if word == 0x00:
            self.regs[0] = value & 0x0007_FF0F  # LATENCY read back at once
        elif word == 0x14:
            if value & 0x7 and not self.regs[0x14] >> 31 & 1:
                raise BoardError("FLASH: programming or erasing flash (FLASH_CR PG/PER/MER1) is not modelled")
            self.regs[0x14] = value
        elif word == 0x10:
            self.regs[0x10] &= ~value
        elif word in (0x08, 0x0C, 0x04):
            if word == 0x08 and value == 0xCDEF89AB and self.regs.get(0x08) == 0x45670123:
                self.regs[0x14] &= ~(1 << 31)
            self.regs[word] = value
        else:
            self.regs[word] = value
