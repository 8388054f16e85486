"""Exception entry and return of the Cortex-M4F (Armv7-M B1.5.6-B1.5.8), done by the board because Unicorn has
no NVIC: the frame pushed on the stack in use (8 words, or 26 with the FP context), 8-byte alignment (CCR.STKALIGN,
xPSR bit 9), LR = EXC_RETURN, PC = the vector from VTOR; on return the frame popped as EXC_RETURN says.

Simplifications (docs/firmware_api.md "The virtual board"): the FP context is stacked whenever CPACR grants CP10/11
(no lazy stacking: the frame is what lazy stacking leaves once the handler used the FPU; EXC_RETURN bit 4 is 0);
Unicorn stays in Thread mode, so IPSR reads 0 inside a handler (ICSR.VECTACTIVE names the active exception);
late arrival is not modelled (tail-chaining is: a pending exception is entered straight after a return);
entry costs ENTRY_CYCLES, return RETURN_CYCLES (Cortex-M4 figures with zero-wait-state memory).
"""

from __future__ import annotations

import struct

from unicorn import arm_const as arm

from pmsm_hil.sim_target.stm32g4.cpu import FP_REGS, FRAME_REGS, Cpu, RegBatch
from pmsm_hil.sim_target.stm32g4.nvic import Nvic
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError
from pmsm_hil.sim_target.stm32g4.scs import SystemControl

ENTRY_CYCLES = 12
RETURN_CYCLES = 10
_BASIC = struct.Struct("<8I")
_EXTENDED = struct.Struct("<8I16III")
VALID_EXC_RETURN = (0xFFFF_FFF1, 0xFFFF_FFF9, 0xFFFF_FFFD, 0xFFFF_FFE1, 0xFFFF_FFE9, 0xFFFF_FFED)


class ExceptionReturnError(BoardError):
    """An EXC_RETURN value the core refuses (UsageFault INVPC); turned into a fault report."""


class ExceptionUnit:
    """Enters and leaves exceptions on `cpu` for `nvic`, with the SCB's VTOR/CPACR/CCR."""

    def __init__(self, cpu: Cpu, nvic: Nvic, scs: SystemControl) -> None:
        self.cpu, self.nvic, self.scs = cpu, nvic, scs
        self.entries = 0
        self._frame = RegBatch(FRAME_REGS)
        self._frame6 = RegBatch(FRAME_REGS[:6])
        self._fp = RegBatch(FP_REGS)

    def vector(self, exc: int) -> int:
        """The handler address of exception `exc` (Thumb bit kept)."""
        return self.cpu.read_u32(self.scs.vtor + 4 * exc)

    def enter(self, exc: int) -> None:
        """Take exception `exc` now (frame, LR, PC, SP, NVIC state)."""
        cpu, uc = self.cpu, self.cpu.uc
        in_thread = not self.nvic.active
        control = cpu.reg(arm.UC_ARM_REG_CONTROL)
        use_psp = in_thread and bool(control & 2)
        fp = self.scs.fpu_enabled
        values = cpu.regs(self._frame)
        ipsr = self.nvic.active[-1] if self.nvic.active else 0
        sp = cpu.reg(arm.UC_ARM_REG_PSP if use_psp else arm.UC_ARM_REG_MSP)
        size = _EXTENDED.size if fp else _BASIC.size
        aligned = bool(self.scs.ccr & 0x200) and bool(sp & 4)
        frame_sp = (sp - size) & ~4 if self.scs.ccr & 0x200 else sp - size
        values[7] = (values[7] & ~0x1FF & ~(1 << 9)) | ipsr | ((1 << 9) if aligned else 0) | (1 << 24)
        if fp:
            fvals = cpu.regs(self._fp)
            data = _EXTENDED.pack(*values, *fvals, 0)
        else:
            data = _BASIC.pack(*values)
        uc.mem_write(frame_sp, data)
        if use_psp:
            cpu.set_reg(arm.UC_ARM_REG_CONTROL, control & ~2 & ~4)
            cpu.set_reg(arm.UC_ARM_REG_PSP, frame_sp)
        else:
            cpu.set_reg(arm.UC_ARM_REG_CONTROL, control & ~4)
            cpu.set_reg(arm.UC_ARM_REG_MSP, frame_sp)
        exc_return = 0xFFFF_FFE1 if fp else 0xFFFF_FFF1
        if in_thread:
            exc_return |= 0xC if use_psp else 0x8
        cpu.set_reg(arm.UC_ARM_REG_LR, exc_return)
        cpu.set_reg(arm.UC_ARM_REG_XPSR, 1 << 24)
        self.nvic.taken(exc)
        self.entries += 1
        cpu.counter.count += ENTRY_CYCLES
        cpu.set_reg(arm.UC_ARM_REG_PC, self.vector(exc) & ~1)

    def leave(self, exc_return: int) -> int:
        """Return from the active exception as `exc_return` says; the exception left. Raises
        ExceptionReturnError for a value the core refuses (INVPC)."""
        cpu, uc = self.cpu, self.cpu.uc
        exc_return |= 1
        if exc_return not in VALID_EXC_RETURN or not self.nvic.active:
            raise ExceptionReturnError(f"EXC_RETURN {exc_return:#010x} with active {self.nvic.active}")
        exc = self.nvic.active[-1]
        to_thread = bool(exc_return & 8)
        if to_thread != (len(self.nvic.active) == 1):
            raise ExceptionReturnError(f"EXC_RETURN {exc_return:#010x} does not match the nesting {self.nvic.active}")
        use_psp = bool(exc_return & 4)
        fp = not exc_return & 0x10
        sp = cpu.reg(arm.UC_ARM_REG_PSP if use_psp else arm.UC_ARM_REG_MSP)
        size = _EXTENDED.size if fp else _BASIC.size
        raw = bytes(uc.mem_read(sp, size))
        values = (_EXTENDED if fp else _BASIC).unpack(raw)
        xpsr = values[7]
        new_sp = sp + size + (4 if xpsr & (1 << 9) else 0)
        self.nvic.returned(exc)
        control = cpu.reg(arm.UC_ARM_REG_CONTROL)
        control = (control | 2) if use_psp else (control & ~2)
        control = (control | 4) if fp else (control & ~4)
        cpu.set_reg(arm.UC_ARM_REG_CONTROL, control)
        cpu.set_reg(arm.UC_ARM_REG_PSP if use_psp else arm.UC_ARM_REG_MSP, new_sp)
        cpu.set_regs(self._frame6, values[:6])
        if fp:
            cpu.set_regs(self._fp, values[8:25])
        cpu.set_reg(arm.UC_ARM_REG_XPSR, xpsr & ~0x1FF & ~(1 << 9))
        cpu.set_reg(arm.UC_ARM_REG_PC, values[6] & ~1)
        cpu.counter.count += RETURN_CYCLES
        return exc
