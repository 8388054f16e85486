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

import ctypes
import struct

from unicorn import UcError
from unicorn import arm_const as arm

from pmsm_hil.sim_target.stm32g4.cpu import FP_REGS, FRAME_REGS, Cpu, RegBatch
from pmsm_hil.sim_target.stm32g4.exc_native import ExcState, exc_state, library
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
    """Enters and leaves exceptions on `cpu` for `nvic`, with the SCB's VTOR/CPACR/CCR. The frames are stacked and
    popped in C (c/exc_frame.c) when `native`, else by the Python reference below (the same steps; the two are
    compared record for record by tests/board/test_native_exc.py)."""

    def __init__(self, cpu: Cpu, nvic: Nvic, scs: SystemControl, *, native: bool = True) -> None:
        self.cpu, self.nvic, self.scs = cpu, nvic, scs
        self.entries = 0
        self._native: tuple[ctypes.CDLL, ExcState] | None = None
        if native:
            self._native = (library(), exc_state(cpu.uc._uch))
            self._native_ref = ctypes.byref(self._native[1])
        # entry: CONTROL, PSP, MSP and the basic frame in one read (the FP registers in a second one)
        self._entry_state = RegBatch((arm.UC_ARM_REG_CONTROL, arm.UC_ARM_REG_PSP, arm.UC_ARM_REG_MSP, *FRAME_REGS))
        self._fp = RegBatch(FP_REGS)
        # entry's stores, in the order the core takes them: CONTROL, the stack pointer in use, LR, xPSR, PC
        self._entry_psp = RegBatch((arm.UC_ARM_REG_CONTROL, arm.UC_ARM_REG_PSP, arm.UC_ARM_REG_LR,
                                    arm.UC_ARM_REG_XPSR, arm.UC_ARM_REG_PC))
        self._entry_msp = RegBatch((arm.UC_ARM_REG_CONTROL, arm.UC_ARM_REG_MSP, arm.UC_ARM_REG_LR,
                                    arm.UC_ARM_REG_XPSR, arm.UC_ARM_REG_PC))
        # return: CONTROL, PSP, MSP read; CONTROL, the stack pointer, r0-r3, r12, lr (FP), xPSR, PC written
        self._return_state = RegBatch((arm.UC_ARM_REG_CONTROL, arm.UC_ARM_REG_PSP, arm.UC_ARM_REG_MSP))
        self._return_psp = RegBatch((arm.UC_ARM_REG_CONTROL, arm.UC_ARM_REG_PSP, *FRAME_REGS[:6]))
        self._return_msp = RegBatch((arm.UC_ARM_REG_CONTROL, arm.UC_ARM_REG_MSP, *FRAME_REGS[:6]))
        self._return_tail = RegBatch((arm.UC_ARM_REG_XPSR, arm.UC_ARM_REG_PC))

    def vector(self, exc: int) -> int:
        """The handler address of exception `exc` (Thumb bit kept)."""
        return self.cpu.read_u32(self.scs.vtor + 4 * exc)

    def enter(self, exc: int) -> None:
        """Take exception `exc` now (frame, LR, PC, SP, NVIC state)."""
        cpu, nvic, scs = self.cpu, self.nvic, self.scs
        if self._native is not None:
            status = self._native[0].hil_exc_enter(self._native_ref, not nvic.active, scs.fpu_enabled, scs.ccr,
                                                   nvic.active[-1] if nvic.active else 0, scs.vtor + 4 * exc)
            if status != 0:
                raise UcError(status)
            nvic.taken(exc)
            self.entries += 1
            cpu.counter.count += ENTRY_CYCLES
            return
        in_thread = not nvic.active
        control, psp, msp, *values = cpu.regs(self._entry_state)
        use_psp = in_thread and bool(control & 2)
        fp = scs.fpu_enabled
        ipsr = nvic.active[-1] if nvic.active else 0
        sp = psp if use_psp else msp
        size = _EXTENDED.size if fp else _BASIC.size
        aligned = bool(scs.ccr & 0x200) and bool(sp & 4)
        frame_sp = (sp - size) & ~4 if scs.ccr & 0x200 else sp - size
        values[7] = (values[7] & ~0x1FF & ~(1 << 9)) | ipsr | ((1 << 9) if aligned else 0) | (1 << 24)
        if fp:
            fvals = cpu.regs(self._fp)
            data = _EXTENDED.pack(*values, *fvals, 0)
        else:
            data = _BASIC.pack(*values)
        cpu.write_bytes(frame_sp, data)
        exc_return = 0xFFFF_FFE1 if fp else 0xFFFF_FFF1
        if in_thread:
            exc_return |= 0xC if use_psp else 0x8
        nvic.taken(exc)
        self.entries += 1
        cpu.counter.count += ENTRY_CYCLES
        handler = self.vector(exc) & ~1
        if use_psp:
            cpu.set_regs(self._entry_psp, (control & ~2 & ~4, frame_sp, exc_return, 1 << 24, handler))
        else:
            cpu.set_regs(self._entry_msp, (control & ~4, frame_sp, exc_return, 1 << 24, handler))

    def leave(self, exc_return: int) -> int:
        """Return from the active exception as `exc_return` says; the exception left. Raises
        ExceptionReturnError for a value the core refuses (INVPC)."""
        cpu = self.cpu
        exc_return |= 1
        if exc_return not in VALID_EXC_RETURN or not self.nvic.active:
            raise ExceptionReturnError(f"EXC_RETURN {exc_return:#010x} with active {self.nvic.active}")
        exc = self.nvic.active[-1]
        to_thread = bool(exc_return & 8)
        if to_thread != (len(self.nvic.active) == 1):
            raise ExceptionReturnError(f"EXC_RETURN {exc_return:#010x} does not match the nesting {self.nvic.active}")
        use_psp = bool(exc_return & 4)
        fp = not exc_return & 0x10
        if self._native is not None:
            status = self._native[0].hil_exc_leave(self._native_ref, use_psp, fp)
            if status != 0:
                raise UcError(status)
            self.nvic.returned(exc)
            cpu.counter.count += RETURN_CYCLES
            return exc
        control, psp, msp = cpu.regs(self._return_state)
        sp = psp if use_psp else msp
        size = _EXTENDED.size if fp else _BASIC.size
        raw = cpu.read_bytes(sp, size)
        values = (_EXTENDED if fp else _BASIC).unpack(raw)
        xpsr = values[7]
        new_sp = sp + size + (4 if xpsr & (1 << 9) else 0)
        self.nvic.returned(exc)
        control = (control | 2) if use_psp else (control & ~2)
        control = (control | 4) if fp else (control & ~4)
        cpu.set_regs(self._return_psp if use_psp else self._return_msp, (control, new_sp, *values[:6]))
        if fp:
            cpu.set_regs(self._fp, values[8:25])
        cpu.set_regs(self._return_tail, (xpsr & ~0x1FF & ~(1 << 9), values[6] & ~1))
        cpu.counter.count += RETURN_CYCLES
        return exc
