"""The board's core in C (c/board_core.c): the NVIC's and SysTick's state in fixed-size C structs that the Python
Nvic and SysTick objects read and write through ctypes, and the scheduler loop of `Board.run_until` as one call
into C per call. Compiled with the host C compiler on first use into the firmware cache, as the instruction counter
is."""

from __future__ import annotations

import ctypes
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pmsm_hil.sim_target.firmware import FirmwareError
from pmsm_hil.sim_target.fw_build import host_library

SOURCE = Path(__file__).with_name("c") / "board_core.c"
EXC_MAX = 128
ACTIVE_MAX = 64
MODELS_MAX = 64
LOG_MAX = 4096
IDLE_CACHE = 64

#: hil_core_run's results (c/board_core.c)
DONE, PY_ERROR, UC_ERROR, INTERRUPT, UNMAPPED, BAD_RETURN, LOG_FULL = 0, 2, 3, 4, 5, 6, 7

PY_ADVANCE = ctypes.CFUNCTYPE(None, ctypes.c_uint64, ctypes.c_int64)
PY_NEXT_EVENT = ctypes.CFUNCTYPE(ctypes.c_int64, ctypes.c_uint64, ctypes.c_uint64, ctypes.c_int64,
                                 ctypes.POINTER(ctypes.c_int64))
PY_QUIET = ctypes.CFUNCTYPE(ctypes.c_uint64, ctypes.c_uint64)
PY_NEXT_EACH = ctypes.CFUNCTYPE(None, ctypes.c_uint64, ctypes.c_int64)


class CoreBuildError(FirmwareError):
    """The board's core could not be compiled (no host C compiler, or the compiler failed)."""


class NvicState(ctypes.Structure):
    """Mirror of hil_nvic_t."""

    _fields_ = [("enabled", ctypes.c_uint8 * EXC_MAX), ("priority", ctypes.c_uint8 * EXC_MAX),
                ("pending", ctypes.c_uint8 * EXC_MAX), ("asserted", ctypes.c_uint8 * EXC_MAX),
                ("has_assert", ctypes.c_uint8 * EXC_MAX), ("assert_at", ctypes.c_int64 * EXC_MAX),
                ("active", ctypes.c_int32 * ACTIVE_MAX), ("n_active", ctypes.c_int32), ("prigroup", ctypes.c_int32),
                ("size", ctypes.c_int32), ("pad", ctypes.c_int32)]


class SysTickState(ctypes.Structure):
    """Mirror of hil_systick_t."""

    _fields_ = [("ctrl", ctypes.c_uint32), ("load", ctypes.c_uint32), ("anchor", ctypes.c_int64),
                ("anchor_val", ctypes.c_int64), ("wraps", ctypes.c_int64), ("countflag", ctypes.c_int32),
                ("pad", ctypes.c_int32)]


class PeriphOps(ctypes.Structure):
    """Mirror of hil_periph_ops_t (c/periph_ops.h)."""

    _fields_ = [("self", ctypes.c_void_p), ("next_event", ctypes.c_void_p), ("advance", ctypes.c_void_p)]


class IrqSink(ctypes.Structure):
    """Mirror of hil_irq_sink_t (c/periph_ops.h)."""

    _fields_ = [("board", ctypes.c_void_p), ("assert_line", ctypes.c_void_p), ("withdraw_line", ctypes.c_void_p),
                ("touched", ctypes.c_void_p)]


class ModelSlot(ctypes.Structure):
    """Mirror of hil_model_t."""

    _fields_ = [("ops", PeriphOps), ("python", ctypes.c_uint8), ("has_advance", ctypes.c_uint8),
                ("has_next", ctypes.c_uint8), ("in_group", ctypes.c_uint8), ("may_rest", ctypes.c_uint8),
                ("resting", ctypes.c_uint8), ("woken", ctypes.c_uint8), ("event_driven", ctypes.c_uint8),
                ("touched", ctypes.c_uint8), ("pad", ctypes.c_uint8 * 7), ("due", ctypes.c_int64)]


class CoreState(ctypes.Structure):
    """Mirror of hil_core_t."""

    _fields_ = [("nvic", NvicState), ("systick", SysTickState), ("counter", ctypes.c_void_p),
                ("uc", ctypes.c_void_p), ("emu_start", ctypes.c_void_p), ("emu_stop", ctypes.c_void_p),
                ("reg_read_batch", ctypes.c_void_p), ("reg_write_batch", ctypes.c_void_p),
                ("mem_read", ctypes.c_void_p),
                ("reg_pc", ctypes.c_int32), ("reg_primask", ctypes.c_int32), ("reg_basepri", ctypes.c_int32),
                ("pad0", ctypes.c_int32),
                ("exc", ctypes.c_void_p), ("exc_enter", ctypes.c_void_p), ("exc_leave", ctypes.c_void_p),
                ("vtor", ctypes.c_uint32), ("ccr", ctypes.c_uint32), ("fp", ctypes.c_int32),
                ("sleep_on_exit", ctypes.c_int32),
                ("py_advance", ctypes.c_void_p), ("py_next_event", ctypes.c_void_p), ("py_quiet", ctypes.c_void_p),
                ("py_next_each", ctypes.c_void_p), ("py_error", ctypes.c_void_p),
                ("n_models", ctypes.c_int32), ("group_touched", ctypes.c_uint8), ("sleeping", ctypes.c_uint8),
                ("rest_on_entry", ctypes.c_uint8), ("pad1", ctypes.c_uint8), ("models", ModelSlot * MODELS_MAX),
                ("group_due", ctypes.c_int64), ("settled_at", ctypes.c_int64), ("sleep_cycles", ctypes.c_int64),
                ("handler_cycles", ctypes.c_int64), ("exc_entries", ctypes.c_int64),
                ("entry_exc", ctypes.c_int32 * ACTIVE_MAX), ("entry_at", ctypes.c_int64 * ACTIVE_MAX),
                ("n_entry", ctypes.c_int32), ("n_log", ctypes.c_int32),
                ("log_exc", ctypes.c_int32 * LOG_MAX), ("log_kind", ctypes.c_int32 * LOG_MAX),
                ("log_value", ctypes.c_int64 * LOG_MAX),
                ("stop_kind", ctypes.c_int32), ("intno", ctypes.c_int32), ("access", ctypes.c_int32),
                ("uc_error", ctypes.c_int32), ("address", ctypes.c_uint64),
                ("idle_pc", ctypes.c_uint32 * IDLE_CACHE), ("idle_hit", ctypes.c_int8 * IDLE_CACHE),
                ("mem_protect", ctypes.c_void_p), ("ram_base", ctypes.c_uint64 * 2), ("ram_span", ctypes.c_uint64 * 2),
                ("ram_exec", ctypes.c_void_p)]


class ScsState(ctypes.Structure):
    """Mirror of hil_scs_t: the System Control Space page's C callbacks and their Python fallbacks."""

    _fields_ = [("core", ctypes.c_void_p), ("fallback", ctypes.c_void_p), ("fallback_user", ctypes.c_void_p),
                ("fallback_write", ctypes.c_void_p), ("fallback_write_user", ctypes.c_void_p)]


OPS_NEXT_EVENT = ctypes.CFUNCTYPE(ctypes.c_int64, ctypes.c_void_p, ctypes.c_int64)
OPS_ADVANCE = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int64)


def trampoline_ops(model: Any, on_error: Callable[[BaseException], None]) -> PeriphOps:
    """A Python model behind hil_periph_ops_t (c/periph_ops.h): its `next_event` and `advance` through callbacks of
    that signature (None as -1), an exception handed to `on_error` (which stops the core). The board calls its Python
    models in batches instead (one call for every Python model due); this is the single-model form, for a model
    that must sit in the ops list as a C one does (the trampolines are kept on the returned structure)."""

    def next_event(_self: int | None, now: int) -> int:
        try:
            at = model.next_event(now)
        except BaseException as exc:
            on_error(exc)
            return -1
        return -1 if at is None else int(at)

    def advance(_self: int | None, now: int) -> None:
        try:
            model.advance(now)
        except BaseException as exc:
            on_error(exc)

    callbacks = (OPS_NEXT_EVENT(next_event), OPS_ADVANCE(advance))
    ops = PeriphOps(None, address(callbacks[0]), address(callbacks[1]))
    ops.__dict__["keep"] = callbacks
    return ops


def new_core() -> CoreState:
    """A zeroed core state with no event due, nothing settled and an empty idle-loop cache."""
    core = CoreState()
    core.group_due = -1
    core.settled_at = -1
    for slot in core.models:
        slot.due = -1
    for i in range(IDLE_CACHE):
        core.idle_hit[i] = -1
    return core


_LIB: ctypes.PyDLL | None = None


def library() -> ctypes.PyDLL:
    """The compiled core (built on first use), its functions typed; loaded keeping the GIL (its loop calls back into
    Python)."""
    global _LIB
    if _LIB is None:
        lib = ctypes.PyDLL(str(host_library(SOURCE, "hil_board_core", "the stm32g4 board's core", CoreBuildError)))
        lib.hil_core_run.argtypes = [ctypes.c_void_p, ctypes.c_int64, ctypes.c_int]
        lib.hil_core_run.restype = ctypes.c_int
        lib.hil_core_assert_line.argtypes = [ctypes.c_void_p, ctypes.c_int]
        lib.hil_core_assert_line.restype = None
        lib.hil_core_withdraw_line.argtypes = [ctypes.c_void_p, ctypes.c_int]
        lib.hil_core_withdraw_line.restype = None
        lib.hil_core_best_pending.argtypes = [ctypes.c_void_p]
        lib.hil_core_best_pending.restype = ctypes.c_int
        check_size(lib.hil_core_size, "the board's core: hil_core_t", CoreState)
        _LIB = lib
    return _LIB


def check_size(size_fn: Any, what: str, mirror: type[ctypes.Structure]) -> None:
    """CoreBuildError naming `what` when the C struct's size (`size_fn()`, an int64 function of the library) is not
    its ctypes mirror's."""
    size_fn.restype = ctypes.c_int64
    if size_fn() != ctypes.sizeof(mirror):
        raise CoreBuildError(f"{what} is {size_fn()} bytes, its mirror {ctypes.sizeof(mirror)}")


def address(fn: Any) -> int:
    """The address of a ctypes function or callback."""
    return int(ctypes.cast(fn, ctypes.c_void_p).value or 0)
