"""The board's clock: a native Unicorn block hook (c/insn_count.c) that counts the Thumb instructions the core
executes and stops it at the slice's limit, so that no Python runs per block. Compiled with the host C compiler
on first use into the firmware cache (keyed by its source), as the QEMU target's plugin is."""

from __future__ import annotations

import ctypes
from pathlib import Path

from pmsm_hil.sim_target.firmware import FirmwareError
from pmsm_hil.sim_target.fw_build import host_library

SOURCE = Path(__file__).with_name("c") / "insn_count.c"
REGIONS = 6
CACHE = 1024


class CounterBuildError(FirmwareError):
    """The instruction counter could not be compiled (no host C compiler, or the compiler failed)."""


class CounterState(ctypes.Structure):
    """Mirror of hil_counter_t (c/insn_count.c)."""

    _fields_ = [("count", ctypes.c_uint64), ("limit", ctypes.c_uint64), ("stop", ctypes.c_void_p),
                ("n_regions", ctypes.c_uint32), ("base", ctypes.c_uint32 * REGIONS),
                ("size", ctypes.c_uint32 * REGIONS), ("host", ctypes.c_void_p * REGIONS),
                ("unknown_blocks", ctypes.c_uint64), ("n_fixed", ctypes.c_uint32), ("pad", ctypes.c_uint32),
                ("cache_address", ctypes.c_uint32 * CACHE), ("cache_size", ctypes.c_uint32 * CACHE),
                ("cache_count", ctypes.c_uint32 * CACHE), ("ram_exec", ctypes.c_void_p),
                ("ram_base", ctypes.c_uint32 * 2), ("ram_span", ctypes.c_uint32 * 2)]

    def forget_blocks(self) -> None:
        """Empty the table of decoded blocks (the code of the fixed regions was written)."""
        ctypes.memset(ctypes.addressof(self.cache_size), 0, ctypes.sizeof(self.cache_size))


def library_path() -> Path:
    """The compiled counter (built on first use)."""
    return host_library(SOURCE, "hil_insn_count", "the stm32g4 board's instruction counter", CounterBuildError)


_LIB: ctypes.CDLL | None = None


def _library() -> ctypes.CDLL:
    global _LIB
    if _LIB is None:
        _LIB = ctypes.CDLL(str(library_path()))
    return _LIB


def hook_function() -> int:
    """Address of hil_counter_block (a uc_cb_hookcode_t)."""
    return int(ctypes.cast(_library().hil_counter_block, ctypes.c_void_p).value or 0)


def tlb_fill_function() -> int:
    """Address of hil_counter_tlb_fill (a uc_cb_tlbevent_t whose user data is the CounterState)."""
    return int(ctypes.cast(_library().hil_counter_tlb_fill, ctypes.c_void_p).value or 0)
