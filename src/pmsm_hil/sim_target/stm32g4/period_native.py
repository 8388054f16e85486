"""The board link's common control period in C (c/board_period.c): its state (a ctypes mirror of
hil_board_period_t, shared with BoardLink) and the library, compiled with the host C compiler on first use into the
firmware cache, as the board's core is."""

from __future__ import annotations

import ctypes
from pathlib import Path

from pmsm_hil.sim_target.fw_build import host_library
from pmsm_hil.sim_target.stm32g4.core_native import CoreBuildError, check_size

SOURCE = Path(__file__).with_name("c") / "board_period.c"
#: the periods' counters the C period holds until Python reads them
RING = 1024
HELD_MAX = 4
#: resume_rc: the period stopped before the core ran (a Python listener raised in the break comparator's call)
BEFORE_RUN = -1

_I64 = ctypes.c_int64
_P = ctypes.c_void_p


class PeriodState(ctypes.Structure):
    """Mirror of hil_board_period_t."""

    _fields_ = [("core", _P), ("run", _P), ("count", _P), ("sleep_cycles", _P), ("handler_cycles", _P),
                ("exc_entries", _P), ("tim", _P), ("set_break_pin", _P), ("late_writes", _P),
                ("first_late_update", _P), ("bdtr", _P), ("enc_theta_m", _P), ("enc_omega_m", _P),
                ("enc_period_start", _P), ("held", _P * HELD_MAX), ("py_held", _P),
                ("n_held", ctypes.c_int32), ("pole_pairs", ctypes.c_int32), ("has_break", ctypes.c_int32),
                ("break_active_low", ctypes.c_int32), ("enabled", ctypes.c_int32), ("pad0", ctypes.c_int32),
                ("hclk_hz", ctypes.c_double), ("break_limit_a", ctypes.c_double), ("period_cycles", _I64),
                ("wake", ctypes.c_int32), ("resume", ctypes.c_int32), ("resume_rc", ctypes.c_int32),
                ("has_theta_e", ctypes.c_int32), ("stale", ctypes.c_int32), ("pad1", ctypes.c_int32),
                ("theta_m", ctypes.c_double), ("theta_e", ctypes.c_double), ("omega_m", ctypes.c_double),
                ("period_start", _I64), ("signals", ctypes.c_double * 4),
                ("sleep0", _I64), ("isr0", _I64), ("entries0", _I64), ("late0", _I64),
                ("periods", _I64), ("late_first_period", _I64), ("frames_tx", _I64), ("wall_ns", _I64),
                ("in_c", _I64), ("head", _I64), ("tail", _I64),
                ("isr", _I64 * RING), ("sleep", _I64 * RING), ("late", _I64 * RING), ("entries", _I64 * RING)]


def new_state() -> PeriodState:
    """A state with the C period off, no first late period and no angle yet."""
    state = PeriodState()
    state.late_first_period = -1
    return state


_LIB: ctypes.PyDLL | None = None


def library() -> ctypes.PyDLL:
    """The compiled period (built on first use); called keeping the GIL from Python (BoardLink.send), without it from
    the native loop's board link."""
    global _LIB
    if _LIB is None:
        lib = ctypes.PyDLL(str(host_library(SOURCE, "hil_board_period", "the stm32g4 board's period",
                                            CoreBuildError)))
        lib.hil_board_period.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]
        lib.hil_board_period.restype = ctypes.c_int
        check_size(lib.hil_board_period_size, "the board's period: hil_board_period_t", PeriodState)
        _LIB = lib
    return _LIB
