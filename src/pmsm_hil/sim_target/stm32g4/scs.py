"""The System Control Space (0xE000E000, PM0214 chapter 4) and the core's debug blocks: NVIC registers, SCB
(CPUID, ICSR, VTOR, AIRCR, SCR, CCR, SHPR1-3, SHCSR, CFSR, HFSR, MMFAR, BFAR, CPACR, FPCCR/FPCAR/FPDSCR), STIR,
SysTick, CoreDebug DEMCR, DWT (CTRL, CYCCNT) and DBGMCU (IDCODE, CR, freeze registers)."""

from __future__ import annotations

from collections.abc import Callable

from pmsm_hil.sim_target.stm32g4.core_native import SysTickState
from pmsm_hil.sim_target.stm32g4.nvic import PENDSV, SYSTICK, Nvic
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from pmsm_hil.sim_target.stm32g4.systick import SysTick

CPUID = 0x410F_C241  # Cortex-M4 r0p1
AIRCR_VECTKEY = 0x05FA


class SystemControl:
    """SCB, NVIC registers, SysTick and the debug blocks; `where()` names the firmware's pc for errors."""

    def __init__(self, nvic: Nvic, idcode: int, where: Callable[[], str], on_reset: Callable[[], None],
                 pend_systick: Callable[[int], None], systick: SysTickState | None = None) -> None:
        self.nvic = nvic
        self.idcode = idcode
        self._where = where
        self._on_reset = on_reset
        self.systick = SysTick(pend_systick, systick)
        self.vtor = 0
        self.scr = 0
        self.ccr = 0x200  # STKALIGN
        self.shcsr = 0
        self.cfsr = 0
        self.hfsr = 0
        self.mmfar = 0
        self.bfar = 0
        self.cpacr = 0
        self.fpccr = 0xC000_0000  # ASPEN, LSPEN
        self.fpcar = 0
        self.fpdscr = 0
        self.actlr = 0
        self.demcr = 0
        self.dwt_ctrl = 0x4000_0000  # NUMCOMP = 4
        self.cyccnt_base = 0  # CYCCNT = now - cyccnt_base while counting
        self.cyccnt_frozen = 0
        self.dbgmcu = [0, 0, 0, 0]  # CR, APB1FZR1, APB1FZR2, APB2FZR

    @property
    def fpu_enabled(self) -> bool:
        """CP10 and CP11 granted (CPACR): the FPU is on and exception frames carry the FP context."""
        return (self.cpacr >> 20) & 0xF != 0

    @property
    def sleep_on_exit(self) -> bool:
        return bool(self.scr & 2)

    def _unmodelled(self, base: int, offset: int, access: str) -> BoardError:
        return BoardError(f"{access} of core register {base + offset:#010x} (System Control Space), which the board "
                          f"does not model, at {self._where()}")

    # --- 0xE000E000 page ---------------------------------------------------------------------------------------------

    def read(self, offset: int, size: int, now: int) -> int:
        nvic_value = self.nvic.read(offset, size)
        if nvic_value is not None:
            return nvic_value
        if 0x10 <= offset < 0x20:
            return self.systick.read(offset & ~3, now)
        if 0xD18 <= offset < 0xD24:  # SHPR1-3: bytes = priorities of exceptions 4..15
            first = 4 + offset - 0xD18
            return int.from_bytes(bytes(self.nvic.priority[first + i] for i in range(size)), "little")
        if 0xD28 <= offset < 0xD2C:  # CFSR (byte/halfword access of MMFSR, BFSR, UFSR allowed)
            return (self.cfsr >> (8 * (offset - 0xD28))) & ((1 << (8 * size)) - 1)
        regs = {0x004: 6, 0x008: self.actlr, 0xD00: CPUID, 0xD04: self._icsr(), 0xD08: self.vtor,
                0xD0C: (0xFA05 << 16) | (self.nvic.prigroup << 8), 0xD10: self.scr, 0xD14: self.ccr,
                0xD24: self.shcsr, 0xD2C: self.hfsr, 0xD30: 0, 0xD34: self.mmfar, 0xD38: self.bfar, 0xD3C: 0,
                0xD88: self.cpacr, 0xDF0: 0, 0xDFC: self.demcr, 0xF34: self.fpccr, 0xF38: self.fpcar,
                0xF3C: self.fpdscr}
        if offset & ~3 in regs and offset & 3 == 0:
            return regs[offset] & ((1 << (8 * size)) - 1)
        if 0xD40 <= offset < 0xD80 or 0xFD0 <= offset < 0x1000:  # feature and ID registers
            return 0
        raise self._unmodelled(0xE000_E000, offset, "read")

    def _icsr(self) -> int:
        active = self.nvic.active[-1] if self.nvic.active else 0
        pend = self.nvic.best_pending() or 0
        pending = self.nvic.pending
        return (active | (pend << 12) | ((1 << 22) if pending else 0) | ((1 << 28) if PENDSV in pending else 0)
                | ((1 << 26) if SYSTICK in pending else 0))

    def write(self, offset: int, size: int, value: int, now: int) -> None:
        if self.nvic.write(offset, size, value):
            return
        if 0x10 <= offset < 0x20:
            self.systick.write(offset & ~3, value, now)
        elif 0xD18 <= offset < 0xD24:
            for i in range(size):
                self.nvic.priority[4 + offset - 0xD18 + i] = (value >> (8 * i)) & 0xF0
        elif 0xD28 <= offset < 0xD2C:  # write 1 to clear
            self.cfsr &= ~(value << (8 * (offset - 0xD28)))
        elif offset == 0xD04:
            if value >> 28 & 1:
                self.nvic.pending.add(PENDSV)
            if value >> 27 & 1:
                self.nvic.pending.discard(PENDSV)
            if value >> 26 & 1:
                self.nvic.pending.add(SYSTICK)
            if value >> 25 & 1:
                self.nvic.pending.discard(SYSTICK)
        elif offset == 0xD08:
            self.vtor = value & 0xFFFF_FF80
        elif offset == 0xD0C:
            if value >> 16 != AIRCR_VECTKEY:
                return  # ignored without the key, as on the chip
            self.nvic.prigroup = (value >> 8) & 7
            if value & 4:  # SYSRESETREQ
                self._on_reset()
        elif offset == 0xD10:
            self.scr = value & 0x16
        elif offset == 0xD14:
            self.ccr = value & 0x31B | 0x200
        elif offset == 0xD24:
            self.shcsr = value & 0x7_0000
            for exc, bit in ((4, 16), (5, 17), (6, 18)):
                self.nvic.enabled[exc] = value >> bit & 1
        elif offset == 0xD2C:
            self.hfsr &= ~value
        elif offset == 0xD88:
            self.cpacr = value & 0x00F0_0000
        elif offset == 0xDFC:
            self.demcr = value & 0x010F_07F1
        elif offset == 0xF00:  # STIR
            self.nvic.pending.add(16 + (value & 0x1FF))
        elif offset == 0xF34:
            self.fpccr = value & 0xC000_01FB
        elif offset == 0xF38:
            self.fpcar = value & ~7
        elif offset == 0xF3C:
            self.fpdscr = value & 0x07C0_0000
        elif offset in (0x008, 0xD34, 0xD38):
            if offset == 0x008:
                self.actlr = value
        else:
            raise self._unmodelled(0xE000_E000, offset, "write")

    # --- DWT (0xE0001000) -----------------------------------------------------------------------------------------

    def dwt_read(self, offset: int, size: int, now: int) -> int:
        if offset == 0x000:
            return self.dwt_ctrl
        if offset == 0x004:
            return (now - self.cyccnt_base) & 0xFFFF_FFFF if self.dwt_ctrl & 1 else self.cyccnt_frozen
        if offset >= 0xFD0 or 0x008 <= offset < 0x100:
            return 0
        raise self._unmodelled(0xE000_1000, offset, "read")

    def dwt_write(self, offset: int, size: int, value: int, now: int) -> None:
        if offset == 0x000:
            counting = bool(self.dwt_ctrl & 1)
            if counting and not value & 1:
                self.cyccnt_frozen = (now - self.cyccnt_base) & 0xFFFF_FFFF
            elif not counting and value & 1:
                self.cyccnt_base = now - self.cyccnt_frozen
            self.dwt_ctrl = (self.dwt_ctrl & 0xF000_0000) | (value & 0x0FFF_FFFF)
        elif offset == 0x004:
            self.cyccnt_frozen = value
            self.cyccnt_base = now - value
        elif 0x008 <= offset < 0x100:
            pass  # the profiling counters (CPICNT ...) and comparators: accepted, not counting
        else:
            raise self._unmodelled(0xE000_1000, offset, "write")

    # --- DBGMCU (0xE0042000) --------------------------------------------------------------------------------------

    def dbgmcu_read(self, offset: int, size: int, now: int) -> int:
        if offset == 0:
            return self.idcode
        if offset in (4, 8, 12, 16):
            return self.dbgmcu[offset // 4 - 1]
        raise self._unmodelled(0xE004_2000, offset, "read")

    def dbgmcu_write(self, offset: int, size: int, value: int, now: int) -> None:
        if offset in (4, 8, 12, 16):
            self.dbgmcu[offset // 4 - 1] = value
        else:
            raise self._unmodelled(0xE004_2000, offset, "write")
