"""The board's C paths (c/exc_frame.c): exception entry and return frames (one call into our library per entry or
return instead of several into Unicorn, the same steps as the Python reference in exceptions.py) and the DWT page's
reads as a Unicorn MMIO callback of the library itself (no Python frame per access). Compiled with the host C
compiler on first use into the firmware cache, as the instruction counter is."""

from __future__ import annotations

import ctypes
from pathlib import Path
from typing import Any

from unicorn import arm_const as arm
from unicorn.unicorn_py3.unicorn import uclib

from pmsm_hil.sim_target.firmware import FirmwareError
from pmsm_hil.sim_target.fw_build import host_library
from pmsm_hil.sim_target.stm32g4.cpu import FP_REGS, FRAME_REGS

SOURCE = Path(__file__).with_name("c") / "exc_frame.c"


class ExcFrameBuildError(FirmwareError):
    """The exception-frame library could not be compiled (no host C compiler, or the compiler failed)."""


class ExcState(ctypes.Structure):
    """Mirror of hil_exc_t (c/exc_frame.c)."""

    _fields_ = [("uc", ctypes.c_void_p), ("reg_read_batch", ctypes.c_void_p), ("reg_write_batch", ctypes.c_void_p),
                ("mem_read", ctypes.c_void_p), ("mem_write", ctypes.c_void_p),
                ("reg_control", ctypes.c_int), ("reg_psp", ctypes.c_int), ("reg_msp", ctypes.c_int),
                ("reg_lr", ctypes.c_int), ("reg_xpsr", ctypes.c_int), ("reg_pc", ctypes.c_int),
                ("frame_regs", ctypes.c_int * 8), ("fp_regs", ctypes.c_int * 17)]


class DwtState(ctypes.Structure):
    """Mirror of hil_dwt_t (c/exc_frame.c)."""

    _fields_ = [("count", ctypes.c_void_p), ("cyccnt_base", ctypes.c_int64), ("ctrl", ctypes.c_uint32),
                ("cyccnt_frozen", ctypes.c_uint32), ("fallback", ctypes.c_void_p), ("fallback_user", ctypes.c_void_p)]


_LIB: ctypes.CDLL | None = None


def library() -> ctypes.CDLL:
    """The compiled library (built on first use), its two functions typed."""
    global _LIB
    if _LIB is None:
        lib = ctypes.CDLL(str(host_library(SOURCE, "hil_exc_frame", "the stm32g4 board's exception frames",
                                           ExcFrameBuildError)))
        lib.hil_exc_enter.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_uint32, ctypes.c_uint32,
                                      ctypes.c_uint32]
        lib.hil_exc_enter.restype = ctypes.c_int
        lib.hil_exc_leave.argtypes = [ctypes.c_void_p, ctypes.c_int, ctypes.c_int]
        lib.hil_exc_leave.restype = ctypes.c_int
        _LIB = lib
    return _LIB


def dwt_read_function() -> int:
    """Address of hil_dwt_read (a uc_cb_mmio_read_t)."""
    return _address(library().hil_dwt_read)


def _address(fn: Any) -> int:
    return int(ctypes.cast(fn, ctypes.c_void_p).value or 0)


def exc_state(uch: Any) -> ExcState:
    """The C side's view of the Unicorn instance `uch` (the binding's uc_engine handle)."""
    state = ExcState()
    state.uc = ctypes.cast(uch, ctypes.c_void_p).value
    state.reg_read_batch = _address(uclib.uc_reg_read_batch)
    state.reg_write_batch = _address(uclib.uc_reg_write_batch)
    state.mem_read = _address(uclib.uc_mem_read)
    state.mem_write = _address(uclib.uc_mem_write)
    state.reg_control, state.reg_psp, state.reg_msp = arm.UC_ARM_REG_CONTROL, arm.UC_ARM_REG_PSP, arm.UC_ARM_REG_MSP
    state.reg_lr, state.reg_xpsr, state.reg_pc = arm.UC_ARM_REG_LR, arm.UC_ARM_REG_XPSR, arm.UC_ARM_REG_PC
    state.frame_regs[:] = list(FRAME_REGS)
    state.fp_regs[:] = list(FP_REGS)
    return state
