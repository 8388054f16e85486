"""The board's motor-control peripherals in C (c/tim1.c, c/adc.c; c/tim_gp.c the encoder timer's CNT read): each
library compiled with the host C compiler on first use into the firmware cache (keyed by its source, as the
instruction counter is), their fixed-size state structs mirrored here, the interrupt sink and Python listeners as C
callbacks, and their register pages mapped as Unicorn MMIO callbacks of the libraries themselves (the Python model
behind the board's decoder as the fallback for what the C side leaves to it). `NATIVE` switches the models to C
(False: the Python references in peripherals/tim1.py and peripherals/adc.py, which give the same records:
tests/board/test_native_exc.py)."""

from __future__ import annotations

import ctypes
import hashlib
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

from unicorn import UcError
from unicorn.unicorn_py3.unicorn import MMIO_READ_CFUNC, MMIO_WRITE_CFUNC, uclib

from pmsm_hil.sim_target.firmware import FirmwareError
from pmsm_hil.sim_target.fw_build import cache_dir, host_library

#: the models of TIM1 and ADC1/ADC2 in C (False: the Python references)
NATIVE = True

C_DIR = Path(__file__).with_name("c")


class PeriphBuildError(FirmwareError):
    """A peripheral model's C library could not be compiled (no host C compiler, or the compiler failed)."""


LISTENER_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.c_int64)
LINE_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int)


class IrqSink(ctypes.Structure):
    """Mirror of hil_irq_sink_t (c/periph_ops.h)."""

    _fields_ = [("board", ctypes.c_void_p), ("assert_line", LINE_FN), ("withdraw_line", LINE_FN),
                ("touched", ctypes.c_void_p)]


class PeriphOps(ctypes.Structure):
    """Mirror of hil_periph_ops_t (c/periph_ops.h)."""

    _fields_ = [("self", ctypes.c_void_p), ("next_event", ctypes.c_void_p), ("advance", ctypes.c_void_p)]


NEXT_EVENT_FN = ctypes.CFUNCTYPE(ctypes.c_int64, ctypes.c_void_p, ctypes.c_int64)
ADVANCE_FN = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_int64)


def set_sink(sink: IrqSink, board: int, assert_line: int, withdraw_line: int, touched: int = 0) -> None:
    """Point `sink` at C functions (`assert_line(board, irq)`, `withdraw_line(board, irq)`: an NVIC in C) instead
    of the board's Python; `touched(board, self, write)` (a scheduler in C) hears of the accesses the model's own
    MMIO callbacks serve (0: none)."""
    sink.board = board
    sink.assert_line = LINE_FN(assert_line)
    sink.withdraw_line = LINE_FN(withdraw_line)
    sink.touched = touched or None


class Listener(ctypes.Structure):
    _fields_ = [("fn", ctypes.c_void_p), ("user", ctypes.c_void_p)]


class Match(ctypes.Structure):
    _fields_ = [("at", ctypes.c_int64), ("ch", ctypes.c_int32), ("pad", ctypes.c_int32)]


class Tim1State(ctypes.Structure):
    """Mirror of hil_tim1_t (c/tim1.c)."""

    _fields_ = [("regs", ctypes.c_uint32 * 256), ("present", ctypes.c_uint8 * 256),
                ("psc", ctypes.c_int64), ("arr", ctypes.c_int64), ("ccr", ctypes.c_int64 * 6), ("rep", ctypes.c_int64),
                ("seg_start", ctypes.c_int64), ("seg_from", ctypes.c_int64), ("seg_dir", ctypes.c_int64),
                ("done_until", ctypes.c_int64), ("frozen_cnt", ctypes.c_int64),
                ("updates", ctypes.c_int64), ("last_update", ctypes.c_int64), ("last_trigger", ctypes.c_int64),
                ("late_writes", ctypes.c_int64), ("first_late_update", ctypes.c_int64),
                ("late_counted_at", ctypes.c_int64), ("plan_end", ctypes.c_int64), ("break_trips", ctypes.c_int64),
                ("running", ctypes.c_int32), ("plan_valid", ctypes.c_int32), ("plan_n", ctypes.c_int32),
                ("plan_head", ctypes.c_int32), ("watched_valid", ctypes.c_int32), ("break_pin", ctypes.c_int32),
                ("ocref", ctypes.c_int32 * 6), ("watched", ctypes.c_int32 * 6), ("plan", Match * 6),
                ("n_listeners", ctypes.c_int32 * 6), ("listeners", (Listener * 4) * 6),
                ("irq_up", ctypes.c_int32), ("irq_cc", ctypes.c_int32), ("irq_brk", ctypes.c_int32),
                ("lines_on", ctypes.c_int32 * 3),
                ("sink", IrqSink), ("count", ctypes.c_void_p), ("fallback_read", ctypes.c_void_p),
                ("fallback_write", ctypes.c_void_p), ("fallback_user", ctypes.c_void_p), ("ops", PeriphOps)]


_LIBS: dict[str, ctypes.CDLL] = {}


def _source(name: str) -> Path:
    """c/NAME.c with c/periph_ops.h inlined, in the cache (the library's cache key then covers the header too)."""
    header = (C_DIR / "periph_ops.h").read_text()
    text = (C_DIR / f"{name}.c").read_text().replace('#include "periph_ops.h"', header)
    out = cache_dir() / f"hil_{name}-{hashlib.sha256(text.encode()).hexdigest()[:16]}.c"
    if not out.is_file():
        tmp = out.with_name(f"{out.name}.{os.getpid()}.tmp")
        tmp.write_text(text)
        os.replace(tmp, out)
    return out


def library(name: str) -> ctypes.CDLL:
    """The compiled model `name` ("tim1", "adc"; built on first use)."""
    lib = _LIBS.get(name)
    if lib is None:
        path = host_library(_source(name), f"hil_{name}", f"the stm32g4 board's {name.upper()} model",
                            PeriphBuildError)
        lib = _LIBS[name] = ctypes.CDLL(str(path))
    return lib


def address(fn: Any) -> int:
    """The address of a C function of one of the libraries (or a ctypes callback)."""
    return int(ctypes.cast(fn, ctypes.c_void_p).value or 0)


#: nonzero while a Callbacks object holds an exception (read by the board link's period in C, c/board_period.c)
HELD = ctypes.c_int32(0)


class Callbacks:
    """Python functions the C side calls (interrupt lines, Python listeners): kept alive with their model; an
    exception inside one is held and raised by `check` once the C call returns (ctypes would drop it)."""

    def __init__(self) -> None:
        self.error: BaseException | None = None
        self._keep: list[Any] = []

    def keep(self, obj: Any) -> Any:
        self._keep.append(obj)
        return obj

    def guard(self, fn: Callable[..., None]) -> Callable[..., None]:
        def call(*args: Any) -> None:
            try:
                fn(*args)
            except BaseException as exc:  # raised by check() after the C call
                if self.error is None:
                    self.error = exc
                HELD.value = 1
        return call

    def check(self) -> None:
        if self.error is not None:
            error, self.error = self.error, None
            HELD.value = 0
            raise error

    def sink(self, assert_line: Callable[[int], None], withdraw_line: Callable[[int], None]) -> IrqSink:
        """An interrupt sink whose lines go to `assert_line(irq)` / `withdraw_line(irq)` (the board's NVIC)."""
        up = self.keep(LINE_FN(self.guard(lambda _board, irq: assert_line(irq))))
        down = self.keep(LINE_FN(self.guard(lambda _board, irq: withdraw_line(irq))))
        return IrqSink(None, up, down)


def map_page(cpu: Any, page: int, size: int, read: Callable[[int, int], int],
             write: Callable[[int, int, int], None], native_read: int, native_write: int, state: Any) -> list[Any]:
    """Map [page, page + size) with the C callbacks `native_read` / `native_write` (uc_cb_mmio_read_t /
    uc_cb_mmio_write_t addresses) and `state` (a ctypes Structure with fields fallback_read, fallback_write,
    fallback_user) as their user data: what they leave goes to `read(address, size)` / `write(address, size,
    value)` (the board's decoder), whose exceptions stop the core and are raised by `cpu.run`, as `Cpu.map_mmio`
    does. Returns the callbacks to keep alive."""
    uch = cpu._uch

    def on_read(_handle: int, offset: int, nbytes: int, _user: int) -> int:
        try:
            return read(page + offset, nbytes)
        except BaseException as exc:  # re-raised once the core stopped (by run(), or the board's C core)
            cpu.hook_failed(exc)
            return 0

    def on_write(_handle: int, offset: int, nbytes: int, value: int, _user: int) -> None:
        try:
            write(page + offset, nbytes, value)
        except BaseException as exc:  # re-raised once the core stopped (by run(), or the board's C core)
            cpu.hook_failed(exc)

    fallback_read, fallback_write = MMIO_READ_CFUNC(on_read), MMIO_WRITE_CFUNC(on_write)
    state.fallback_read = address(fallback_read)
    state.fallback_write = address(fallback_write)
    state.fallback_user = None
    c_read, c_write = MMIO_READ_CFUNC(native_read), MMIO_WRITE_CFUNC(native_write)
    status = uclib.uc_mmio_map(uch, page, size, c_read, ctypes.addressof(state), c_write, ctypes.addressof(state))
    if status != 0:
        raise UcError(status)
    return [fallback_read, fallback_write, c_read, c_write, state]
