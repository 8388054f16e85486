"""The virtual STM32G4: the core, its exception logic, the part's peripheral models behind one address decoder,
and the clock that runs them together.

Time is the core's cycle count at HCLK: one per executed instruction (CPI 1, a lower bound: loads, taken
branches, divides and flash wait states cost more on the chip), plus the exception entry and return costs.
The board runs the core in slices up to the earliest peripheral event (the native counter stops the core at
the end of the block that reaches it, so an event is taken at most one basic block late), brings every model
up to the slice's end, takes the pending exception that preempts, and skips the time a WFI sleeps.
"""

from __future__ import annotations

import ctypes
import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from unicorn import UcError
from unicorn import arm_const as arm

from pmsm_hil.sim_target.elf import ElfError, elf_load_segments, elf_symbols
from pmsm_hil.sim_target.stm32g4 import core_native
from pmsm_hil.sim_target.stm32g4 import peripherals as _peripherals_pkg
from pmsm_hil.sim_target.stm32g4.core_native import (
    PY_ADVANCE,
    PY_NEXT_EACH,
    PY_NEXT_EVENT,
    PY_QUIET,
    CoreState,
    IrqSink,
    PeriphOps,
    ScsState,
    new_core,
)
from pmsm_hil.sim_target.stm32g4.counter import CounterState
from pmsm_hil.sim_target.stm32g4.cpu import (
    EXCP_BKPT,
    EXCP_DIVBYZERO,
    EXCP_INVSTATE,
    EXCP_NOCP,
    EXCP_SWI,
    EXCP_UDEF,
    EXCP_UNALIGNED,
    PAGE,
    Cpu,
    RegBatch,
)
from pmsm_hil.sim_target.stm32g4.exc_native import DwtState, dwt_read_function
from pmsm_hil.sim_target.stm32g4.exc_native import library as exc_library
from pmsm_hil.sim_target.stm32g4.exceptions import ExceptionReturnError, ExceptionUnit
from pmsm_hil.sim_target.stm32g4.fault import (
    BFARVALID,
    DIVBYZERO,
    FORCED,
    IBUSERR,
    INVPC,
    INVSTATE,
    NOCP,
    PRECISERR,
    UNALIGNED,
    UNDEFINSTR,
    BoardFaultError,
    where,
)
from pmsm_hil.sim_target.stm32g4.nvic import HARDFAULT, SVCALL, SYSTICK, AssertTimes, Nvic
from pmsm_hil.sim_target.stm32g4.part import FDCAN_RAM_BASE, Part, block_name
from pmsm_hil.sim_target.stm32g4.peripherals.base import REGISTRY, BoardError, Peripheral
from pmsm_hil.sim_target.stm32g4.scs import SystemControl

#: slice length [instructions] while an enabled interrupt is pending but masked (PRIMASK/BASEPRI changes by CPS
#: or MSR are not visible to the board until the slice ends)
MASKED_SLICE = 64
#: the internal reference (VREFINT, ADC1 channel 18; DS12288 typical) [V]
VREFINT_V = 1.212
#: per-exception samples (handler times, latencies) kept for the metrics: the most recent ones
KEEP_SAMPLES = 200_000
#: reset clock: HSI16
RESET_HCLK_HZ = 16_000_000


def load_models() -> None:
    """Import every peripheral model module so that each registers itself."""
    for info in pkgutil.iter_modules(_peripherals_pkg.__path__):
        if info.name != "base":
            importlib.import_module(f"{_peripherals_pkg.__name__}.{info.name}")


@dataclass(slots=True)
class IsrStats:
    """What the board saw of one exception: entries, cycles inside (nested handlers included), latency from
    its line's assertion to entry [cycles]."""

    entries: int = 0
    cycles: list[int] = field(default_factory=list)
    latency: list[int] = field(default_factory=list)


class Board:
    """One virtual part running one firmware image; implements the peripherals' BoardBus."""

    #: the board's C paths (c/exc_frame.c): exception frames and the DWT page's reads (False: the Python reference,
    #: which gives the same records: tests/board/test_native_exc.py)
    NATIVE = True
    #: the scheduler skips the models that cannot change before their next event but through an access the board
    #: sees (TIM1 and the ADCs, advanced together while their earliest event is due or one of them was accessed;
    #: a general-purpose timer that counts encoder edges or is stopped) instead of asking every model at every step
    #: (False: every model at every step, the reference, which gives the same records: tests/board/test_quiet_skip.py)
    SKIP_QUIET = True
    #: the scheduler, the NVIC and SysTick in C (c/board_core.c): one call into C per run_until, the Python models
    #: called from it in batches (needs NATIVE and SKIP_QUIET; False: the Python scheduler above, the reference, which
    #: gives the same records: tests/board/test_native_exc.py)
    NATIVE_CORE = True
    #: the C core caches the next event of each event-driven model (Peripheral.EVENT_DRIVEN: FDCAN1, the watchdogs,
    #: CORDIC) and advances and asks it only when that event is due, after an access to it, a core clock change or a
    #: run-side input (Peripheral.inputs_changed), instead of at every step; and a resting model (`quiet()`: whether
    #: it rests changes only through a register write or a run-side input) is asked again only after one of those,
    #: not after a read nor at each run_until (needs NATIVE_CORE; False: asked at every step, the reference, which
    #: gives the same records: tests/board/test_native_exc.py)
    EVENT_DRIVEN = True
    #: the ISR statistics (`isr`) taken from the C core's log when it is full or when they are read, and the
    #: exception entries counted by the core (`exception_entries`), instead of the log drained after every run_until
    #: and the entries summed over the statistics (needs NATIVE_CORE; False: the reference, which gives the same
    #: records: tests/board/test_native_exc.py)
    LAZY_STATS = True

    def __init__(self, part: Part, elf: str | Path, *, console: Callable[[str, str], None] | None = None,
                 hse_hz: int = 24_000_000) -> None:
        load_models()
        self._hse_hz = hse_hz
        self.part = part
        self.elf = Path(elf)
        self._console = console
        self.console_lines: list[tuple[str, str]] = []
        self._native_core = self.NATIVE_CORE and self.NATIVE and self.SKIP_QUIET
        #: the C core's log goes into `isr` when full or read (LAZY_STATS), not after every run_until
        self._lazy_stats = self._native_core and self.LAZY_STATS
        #: the NVIC's and SysTick's state and the scheduler's counters, read by the C core and the Python objects
        self._core: CoreState = new_core()
        self._core_lib = core_native.library()
        self._core_ref = ctypes.byref(self._core)
        self.cpu = Cpu(part, python_stops=not self._native_core)
        self._core.counter = ctypes.addressof(self.cpu.counter)
        #: where a model's interrupt lines go (a model in C calls it directly; Python models through set_pending and
        #: clear_pending: the same C functions on the same state, with either scheduler)
        self.irq_sink = IrqSink(ctypes.addressof(self._core),
                                core_native.address(self._core_lib.hil_core_assert_line),
                                core_native.address(self._core_lib.hil_core_withdraw_line),
                                core_native.address(self._core_lib.hil_core_touched))
        self.nvic = Nvic(part.irq_count, self._core.nvic)
        self.scs = SystemControl(self.nvic, part.idcode, self.describe_pc, self._reset_request, self._pend_systick,
                                 self._core.systick)
        self.exceptions = ExceptionUnit(self.cpu, self.nvic, self.scs, native=self.NATIVE)
        self.hclk_hz = RESET_HCLK_HZ
        self.peripherals: dict[str, Peripheral] = {}
        self.absent: list[str] = []
        for name in part.peripherals:
            factory = REGISTRY.get(name)
            if factory is None:  # not modelled yet: an access to it is an unmodelled access
                self.absent.append(name)
                continue
            self.peripherals[name] = factory(self)
        self._owner: dict[int, Peripheral] = {}
        self._map_peripherals()
        self._timed = [p for p in self.peripherals.values() if type(p).next_event is not Peripheral.next_event]
        self._timed_set = set(self._timed)
        self._idle_loops: dict[int, bool] = {}
        self._mask_regs = RegBatch((arm.UC_ARM_REG_PRIMASK, arm.UC_ARM_REG_BASEPRI))
        #: the cycle at which the last run_until left every model advanced (nothing can change before the next
        #: call but through the models' own accesses, which advance them first): the next call starts there
        self._settled_at = -1
        self._advancing = [p for p in self.peripherals.values() if type(p).advance is not Peripheral.advance]
        #: the event group (advanced together, skipped while its earliest event is ahead and none was accessed)
        self._group = [p for p in self.peripherals.values() if getattr(p, "EVENT_GROUP", None) == "TIM1"]
        self._group_set = frozenset(self._group)
        self._group_touched = True
        self._group_due: int | None = None
        #: models that may be quiet (a `quiet()` method); those quiet now are skipped until accessed
        self._may_rest = frozenset(p for p in self.peripherals.values() if callable(getattr(p, "quiet", None)))
        self._resting: set[Peripheral] = set()
        self._woken: set[Peripheral] = set()  # resting models accessed since the last step
        self._isr: dict[int, IsrStats] = {}  # by exception number
        self._assert_time = AssertTimes(self._core.nvic)
        self._entry_stack: list[tuple[int, int]] = []  # (exception, cycle of entry)
        #: the analog front end: (adc, channel, cycle) -> volts; channel -1 is VREF+ (the board description's)
        self.analog: Callable[[str, int, int], float] = lambda adc, channel, now: 3.3 if channel < 0 else 0.0
        #: the encoder: (timer, cycle) -> quadrature edges counted so far
        self.encoder: Callable[[str, int], int] = lambda timer, now: 0
        self._load()
        self._symbols: dict[str, int] | None = None
        self._slot: dict[Peripheral, int] = {}
        if self._native_core:
            self._setup_core()

    # --- the scheduler's counters (in the core's state) -----------------------------------------------------------

    @property
    def sleeping(self) -> bool:
        """The core sleeps (WFI, or sleep-on-exit) until a pending interrupt wakes it."""
        return bool(self._core.sleeping)

    @sleeping.setter
    def sleeping(self, value: bool) -> None:
        self._core.sleeping = int(value)

    @property
    def sleep_cycles(self) -> int:
        """Cycles the core slept so far."""
        return int(self._core.sleep_cycles)

    @sleep_cycles.setter
    def sleep_cycles(self, value: int) -> None:
        self._core.sleep_cycles = value

    @property
    def handler_cycles(self) -> int:
        """Cycles spent in exception handlers so far (nested ones counted once)."""
        return int(self._core.handler_cycles)

    @handler_cycles.setter
    def handler_cycles(self, value: int) -> None:
        self._core.handler_cycles = value

    @property
    def isr(self) -> dict[int, IsrStats]:
        """What the board saw of each exception so far, by exception number."""
        if self._lazy_stats and self._core.n_log:
            self._drain()
        return self._isr

    @property
    def exception_entries(self) -> int:
        """Exception entries so far (of every exception: the sum of `isr`'s entries)."""
        if self._lazy_stats:
            return int(self._core.exc_entries)
        return sum(st.entries for st in self.isr.values())

    # --- the C core ---------------------------------------------------------------------------------------------

    def _setup_core(self) -> None:
        """Hand the C core Unicorn's functions, the exception frames, the counter, the models (a model with a
        `native_ops` attribute, a core_native.PeriphOps, is called directly; the others through the batches below)
        and the stop hooks."""
        from unicorn import (
            UC_HOOK_INTR,
            UC_HOOK_MEM_FETCH_UNMAPPED,
            UC_HOOK_MEM_READ_UNMAPPED,
            UC_HOOK_MEM_WRITE_UNMAPPED,
        )
        from unicorn.unicorn_py3.unicorn import uclib

        lib, core, cpu = self._core_lib, self._core, self.cpu
        core.uc = ctypes.cast(cpu.uc._uch, ctypes.c_void_p).value
        core.emu_start = core_native.address(uclib.uc_emu_start)
        core.emu_stop = core_native.address(uclib.uc_emu_stop)
        core.reg_read_batch = core_native.address(uclib.uc_reg_read_batch)
        core.reg_write_batch = core_native.address(uclib.uc_reg_write_batch)
        core.mem_read = core_native.address(uclib.uc_mem_read)
        core.mem_protect = core_native.address(uclib.uc_mem_protect)
        for i, (base, span) in enumerate(cpu.ram):
            core.ram_base[i], core.ram_span[i] = base, span
        core.ram_exec = ctypes.addressof(cpu.ram_exec)
        core.reg_pc, core.reg_primask, core.reg_basepri = arm.UC_ARM_REG_PC, arm.UC_ARM_REG_PRIMASK, \
            arm.UC_ARM_REG_BASEPRI
        native = self.exceptions._native
        assert native is not None
        exc_lib = exc_library()
        core.exc = ctypes.addressof(native[1])
        core.exc_enter = core_native.address(exc_lib.hil_exc_enter)
        core.exc_leave = core_native.address(exc_lib.hil_exc_leave)
        core.py_error = ctypes.addressof(cpu.hook_error)
        self._mirror_scb()
        models = [p for p in self.peripherals.values()
                  if p in self._timed_set or p in self._advancing or p in self._may_rest]
        if len(models) > core_native.MODELS_MAX:
            raise BoardError(f"the board's core holds {core_native.MODELS_MAX} timed models, the part has "
                             f"{len(models)}")
        self._models = models
        self._native_ops: list[PeriphOps] = []
        #: what the models in C held while the core called them directly (raised once its loop returned)
        self._held: list[Callable[[], None]] = []
        for i, p in enumerate(models):
            slot = core.models[i]
            ops = getattr(p, "native_ops", None)
            if ops is not None:
                self._native_ops.append(ops)  # kept alive with whatever it holds (a trampoline's callbacks)
                slot.ops = ops
                set_sink = getattr(p, "set_irq_sink", None)
                if ops.self and set_sink is not None:  # a model in C: its lines and accesses go to the core directly
                    sink = self.irq_sink
                    set_sink(sink.board, sink.assert_line, sink.withdraw_line, sink.touched)
                    self._held.append(p.raise_held)  # type: ignore[attr-defined]
                slot.has_advance, slot.has_next = bool(ops.advance), bool(ops.next_event)
            else:
                slot.python = 1
                slot.has_advance, slot.has_next = p in self._advancing, p in self._timed_set
            slot.in_group = p in self._group_set
            slot.may_rest = p in self._may_rest
            slot.event_driven = self._event_driven(p)
            slot.touched = 1
            slot.due = -1
            slot.woken = p in self._may_rest  # asked whether it rests at the first step
            self._slot[p] = i
        core.n_models = len(models)
        core.rest_on_entry = self.EVENT_DRIVEN
        self._batches: dict[int, tuple[Peripheral, ...]] = {}
        self._callbacks = (PY_ADVANCE(self._py_advance), PY_NEXT_EVENT(self._py_next_event),
                           PY_QUIET(self._py_quiet), PY_NEXT_EACH(self._py_next_each))
        core.py_advance, core.py_next_event, core.py_quiet, core.py_next_each = (
            core_native.address(f) for f in self._callbacks)
        self._hook_handles: list[ctypes.c_size_t] = []
        for kind, fn, ranges in ((UC_HOOK_INTR, lib.hil_core_on_interrupt, [(1, 0)]),
                                 (UC_HOOK_MEM_READ_UNMAPPED | UC_HOOK_MEM_WRITE_UNMAPPED | UC_HOOK_MEM_FETCH_UNMAPPED,
                                  lib.hil_core_on_unmapped, cpu.unmapped_ranges())):
            for begin, end in ranges:
                handle = ctypes.c_size_t()
                status = uclib.uc_hook_add(cpu.uc._uch, ctypes.byref(handle), kind, ctypes.c_void_p(
                    core_native.address(fn)), ctypes.c_void_p(ctypes.addressof(core)), ctypes.c_uint64(begin),
                    ctypes.c_uint64(end))
                if status != 0:
                    raise UcError(status)
                self._hook_handles.append(handle)

    def _event_driven(self, p: Peripheral) -> bool:
        """The C core caches `p`'s next event (EVENT_DRIVEN, outside the event group, without a `quiet`)."""
        return self.EVENT_DRIVEN and type(p).EVENT_DRIVEN and p not in self._group_set and p not in self._may_rest

    def _batch(self, mask: int) -> tuple[Peripheral, ...]:
        batch = self._batches.get(mask)
        if batch is None:
            batch = self._batches[mask] = tuple(p for i, p in enumerate(self._models) if mask >> i & 1)
        return batch

    def _py_advance(self, mask: int, now: int) -> None:
        try:
            for p in self._batch(mask):
                p.advance(now)
        except BaseException as exc:  # raised by run_until once the C loop returned
            self.cpu.hook_failed(exc)

    def _py_next_event(self, active: int, group: int, now: int, group_out: Any) -> int:
        """The earliest next event of the Python models in `active`; the group's (`group`) into `group_out[0]`."""
        best = gbest = -1
        try:
            if active:
                for p in self._batch(active):
                    at = p.next_event(now)
                    if at is not None and (best < 0 or at < best):
                        best = at
            if group:
                for p in self._batch(group):
                    at = p.next_event(now)
                    if at is not None and (gbest < 0 or at < gbest):
                        gbest = at
                group_out[0] = gbest
        except BaseException as exc:
            self.cpu.hook_failed(exc)
        return best

    def _py_next_each(self, mask: int, now: int) -> None:
        """Each event-driven Python model's next event in `mask` into its slot's `due` (-1: none)."""
        try:
            slots = self._core.models
            for p in self._batch(mask):
                at = p.next_event(now)
                slots[self._slot[p]].due = -1 if at is None else at
        except BaseException as exc:
            self.cpu.hook_failed(exc)

    def _py_quiet(self, mask: int) -> int:
        quiet = 0
        try:
            for p in self._batch(mask):
                if p.quiet():  # type: ignore[attr-defined]
                    quiet |= 1 << self._slot[p]
        except BaseException as exc:
            self.cpu.hook_failed(exc)
        return quiet

    def _mirror_scb(self) -> None:
        """The SCB's state the C core's exception entry and return use."""
        core, scs = self._core, self.scs
        core.vtor, core.ccr, core.fp, core.sleep_on_exit = scs.vtor, scs.ccr, scs.fpu_enabled, scs.sleep_on_exit

    # --- set-up -------------------------------------------------------------------------------------------------

    def _map_peripherals(self) -> None:
        pages: set[int] = set()
        for p in self.peripherals.values():
            for chunk in range(p.base >> 8, (p.base + p.size + 0xFF) >> 8):
                if chunk in self._owner:
                    raise BoardError(f"peripheral models {self._owner[chunk].name} and {p.name} overlap at "
                                     f"{chunk << 8:#010x}")
                self._owner[chunk] = p
                pages.add((chunk << 8) & ~(PAGE - 1))
        if "FDCAN1" in self.part.peripherals:
            self.cpu.map_ram(FDCAN_RAM_BASE, 0xC00)
            pages.discard(FDCAN_RAM_BASE & ~(PAGE - 1))
        native = {at: p for p in self.peripherals.values() if (at := getattr(p, "native_page", None)) is not None}
        for page in sorted(pages):
            if page in native:  # a model in C serves its page (the rest of it through the decoder)
                native[page].map_native(self.cpu, self._read, self._write)  # type: ignore[attr-defined]
            else:
                self.cpu.map_mmio(page, PAGE, self._read, self._write)
        scs = self.scs
        scs_store = self._core_store(0xE000_E000, scs.write)

        def scs_write(address: int, size: int, value: int) -> None:
            scs_store(address, size, value)
            if self._native_core:
                self._mirror_scb()

        if self._native_core:  # the NVIC's and SysTick's registers in C, the rest of the page in Python
            lib = self._core_lib
            self._scs_state = ScsState(ctypes.addressof(self._core))
            self.cpu.map_mmio(0xE000_E000, PAGE, self._core_access(0xE000_E000, scs.read), scs_write,
                              native_read=(core_native.address(lib.hil_core_scs_read), self._scs_state),
                              native_write=(core_native.address(lib.hil_core_scs_write), self._scs_state))
        else:
            self.cpu.map_mmio(0xE000_E000, PAGE, self._core_access(0xE000_E000, scs.read), scs_write)
        dwt_read, dwt_store = self._core_access(0xE000_1000, scs.dwt_read), self._core_store(0xE000_1000, scs.dwt_write)
        if self.NATIVE:  # the reads in C (CYCCNT in a timed ISR: no Python per access), the writes in Python
            dwt = self._dwt = DwtState()
            dwt.count = ctypes.addressof(self.cpu.counter) + CounterState.count.offset

            def mirror() -> None:
                dwt.ctrl, dwt.cyccnt_base, dwt.cyccnt_frozen = scs.dwt_ctrl, scs.cyccnt_base, scs.cyccnt_frozen

            def store(address: int, size: int, value: int) -> None:
                dwt_store(address, size, value)
                mirror()

            mirror()
            self.cpu.map_mmio(0xE000_1000, PAGE, dwt_read, store, native_read=(dwt_read_function(), dwt))
        else:
            self.cpu.map_mmio(0xE000_1000, PAGE, dwt_read, dwt_store)
        self.cpu.map_mmio(0xE004_2000, PAGE, self._core_access(0xE004_2000, scs.dbgmcu_read),
                          self._core_store(0xE004_2000, scs.dbgmcu_write))

    def _core_access(self, base: int, read: Callable[[int, int, int], int]) -> Callable[[int, int], int]:
        def access(address: int, size: int) -> int:
            return read(address - base, size, self.cpu.count)
        return access

    def _core_store(self, base: int, write: Callable[[int, int, int, int], None]) -> Callable[[int, int, int], None]:
        def store(address: int, size: int, value: int) -> None:
            write(address - base, size, value, self.cpu.count)
            self.cpu.counter.limit = self.cpu.counter.count  # the schedule is re-made after this block
        return store

    def _load(self) -> None:
        try:
            _, segments = elf_load_segments(self.elf)
        except (ElfError, OSError) as exc:
            raise BoardError(f"stm32g4 target: {exc}") from None
        for address, data in segments:
            if not self._loadable(address, len(data)):
                raise BoardError(f"stm32g4 target: {self.elf} has a segment at {address:#010x} ({len(data)} bytes) "
                                 f"outside {self.part.name}'s flash and SRAM")
            self.cpu.load(address, data)
        self.reset()

    def _loadable(self, address: int, size: int) -> bool:
        part = self.part
        spans = ((0x0800_0000, part.flash_size), (0x2000_0000, part.sram_size + part.ccm_size),
                 (0x1000_0000, part.ccm_size))
        return any(base <= address and address + size <= base + length for base, length in spans)

    def reset(self) -> None:
        """Core reset: SP and PC from the vector table at 0 (flash, booted from main flash)."""
        sp, pc = self.cpu.read_u32(0), self.cpu.read_u32(4)
        if not (pc & 1) or pc == 0xFFFF_FFFF:
            raise BoardError(f"stm32g4 target: {self.elf}: the reset vector {pc:#010x} is no Thumb address (no "
                             "vector table at the start of flash?)")
        self.cpu.set_reg(arm.UC_ARM_REG_MSP, sp)
        self.cpu.set_reg(arm.UC_ARM_REG_CONTROL, 0)
        self.cpu.set_reg(arm.UC_ARM_REG_PC, pc & ~1)
        self.cpu.set_reg(arm.UC_ARM_REG_XPSR, 1 << 24)

    def _reset_request(self) -> None:
        raise BoardError(f"the firmware requested a system reset (AIRCR.SYSRESETREQ) at {self.describe_pc()}: the "
                         "virtual board does not reset during a run")

    # --- BoardBus -----------------------------------------------------------------------------------------------

    def set_pending(self, irq: int) -> None:
        """Assert interrupt line `irq` (c/board_core.c: pending unless active, its latency's start kept, the core
        stopped at its next block when the line is enabled)."""
        self._core_lib.hil_core_assert_line(self._core_ref, irq)

    def _pend_systick(self, at: int) -> None:
        if SYSTICK not in self.nvic.pending:
            self._assert_time[SYSTICK] = at
        self.nvic.pending.add(SYSTICK)

    def clear_pending(self, irq: int) -> None:
        exc = 16 + irq
        if 0 <= exc < self.nvic.size:
            state = self._core.nvic
            state.asserted[exc] = 0
            state.pending[exc] = 0

    def read_memory(self, address: int, size: int) -> bytes:
        return bytes(self.cpu.uc.mem_read(address, size))

    def write_memory(self, address: int, data: bytes) -> None:
        self.cpu.uc.mem_write(address, data)

    def peripheral(self, name: str) -> Peripheral:
        try:
            return self.peripherals[name]
        except KeyError:
            raise BoardError(f"the board has no {name} model (part {self.part.name})") from None

    @property
    def sysclk_hz(self) -> int:
        return self.hclk_hz

    @property
    def hse_hz(self) -> int:
        return self._hse_hz

    def set_hclk(self, hz: int) -> None:
        self.hclk_hz = hz
        core = self._core  # the event-driven models count in core cycles: their next events move
        for i in range(core.n_models):
            slot = core.models[i]
            if slot.event_driven:
                slot.touched = 1

    def model_changed(self, p: Peripheral) -> None:
        """The run side changed model `p` outside a register access (Peripheral.inputs_changed): the scheduler asks
        it again at its next step."""
        self._touch(p)

    def analog_voltage(self, adc: str, channel: int, now: int) -> float:
        if adc == "ADC1" and channel == 18:
            return VREFINT_V
        return self.analog(adc, channel, now)

    def encoder_position(self, timer: str, now: int) -> int:
        return self.encoder(timer, now)

    def log(self, source: str, line: str) -> None:
        """A console line of the firmware (USART2) for the run's log."""
        self.console_lines.append((source, line))
        if self._console is not None:
            self._console(source, line)

    # --- address decoder ----------------------------------------------------------------------------------------

    def describe_pc(self) -> str:
        """`pc 0x... (function+0x..)` of the firmware now (the start of the basic block being executed)."""
        return f"pc {where(self.elf, self.cpu.pc)}"

    def _unmodelled(self, address: int, access: str) -> BoardError:
        name = block_name(address)
        return BoardError(f"{access} of {address:#010x} ({name}, not modelled by the virtual board) at "
                          f"{self.describe_pc()}")

    def _read(self, address: int, size: int) -> int:
        p = self._owner.get(address >> 8)
        if p is None:
            raise self._unmodelled(address, "read")
        self._touch(p, write=False)
        try:
            return p.read(address - p.base, size, self.cpu.count)
        except BoardError as exc:
            raise self._located(exc) from None

    def _located(self, exc: BoardError) -> BoardError:
        """A model's refusal (an unmodelled register or field) with the firmware's pc and function."""
        return exc if isinstance(exc, BoardFaultError) else BoardError(f"{exc}, at {self.describe_pc()}")

    def _write(self, address: int, size: int, value: int) -> None:
        p = self._owner.get(address >> 8)
        if p is None:
            raise self._unmodelled(address, "write")
        self._touch(p)
        try:
            self._store(p, address, size, value, self.cpu.count)
        except BoardError as exc:
            raise self._located(exc) from None

    def _touch(self, p: Peripheral, write: bool = True) -> None:
        """An access reached model `p`: the scheduler asks it (and its event group) again at its next step (a resting
        model, with EVENT_DRIVEN, after a write only: a read leaves its configuration as it is)."""
        if self._native_core:
            if p in self._group_set:
                self._core.group_touched = 1
            elif p in self._slot:
                slot = self._core.models[self._slot[p]]
                if slot.event_driven:
                    slot.touched = 1
                elif slot.resting and (write or not self.EVENT_DRIVEN):
                    slot.woken = 1
        elif p in self._group_set:
            self._group_touched = True
        elif p in self._resting:
            self._woken.add(p)

    def _store(self, p: Peripheral, address: int, size: int, value: int, now: int) -> None:
        """A write to a model's register (by the CPU or a bus master); a model whose next event moved before the
        running slice's end makes the core stop at its next block so that the schedule is re-made."""
        p.write(address - p.base, size, value, now)
        if p in self._timed_set:
            event = p.next_event(now)
            if event is not None and event < self.cpu.counter.limit:
                self.cpu.request_stop()

    # --- BusMaster ----------------------------------------------------------------------------------------------

    def access(self, address: int, size: int, value: int | None = None, *, now: int) -> int:
        """A bus master's (DMA's) load of `size` bytes at `address` (value None: returns them) or store of `value`
        (returns it): a peripheral's registers through its model, as the CPU's accesses, SRAM, CCM-SRAM and the
        FDCAN message RAM directly; flash is read-only, the core's private bus (0xE0000000 up) and unmodelled
        addresses are refused naming the address."""
        p = self._owner.get(address >> 8)
        if p is not None:
            self._touch(p, write=value is not None)
            if value is None:
                return p.read(address - p.base, size, now)
            self._store(p, address, size, value, now)
            return value
        if 0x4000_0000 <= address < 0x6000_0000 and not self._in_message_ram(address, size):
            kind = "read" if value is None else "write"
            raise BoardError(f"bus-master {kind} of {address:#010x} ({block_name(address)}, not modelled by the "
                             "virtual board)")
        if address >= 0xE000_0000:
            raise BoardError(f"bus-master access of {address:#010x}: the core's private peripheral bus is not "
                             "reachable by DMA")
        if value is not None and address < 0x1000_0000:  # flash and its boot alias at 0
            raise BoardError(f"bus-master write of {address:#010x}: flash is read-only to a bus master")
        try:
            if value is None:
                return int.from_bytes(self.cpu.uc.mem_read(address, size), "little")
            self.cpu.uc.mem_write(address, (value & ((1 << (8 * size)) - 1)).to_bytes(size, "little"))
        except UcError:
            raise BoardError(f"bus-master access of {address:#010x}: no memory of {self.part.name} there") from None
        return value

    def _in_message_ram(self, address: int, size: int) -> bool:
        return "FDCAN1" in self.part.peripherals and address >= FDCAN_RAM_BASE and \
            address + size <= FDCAN_RAM_BASE + 0xC00

    # --- running ------------------------------------------------------------------------------------------------

    @property
    def now(self) -> int:
        """The board's time [HCLK cycles since reset]."""
        return self.cpu.count

    def next_event(self, now: int) -> int | None:
        """The earliest cycle after `now` at which a model (or SysTick) changes state by itself."""
        best = self.scs.systick.next_event(now)
        for p in self._timed:
            event = p.next_event(now)
            if event is not None and (best is None or event < best):
                best = event
        return best

    def _masks(self) -> tuple[bool, int]:
        primask, basepri = self.cpu.regs(self._mask_regs)
        return bool(primask & 1), basepri

    def _enter(self, exc: int) -> None:
        stats = self._isr.setdefault(exc, IsrStats())
        stats.entries += 1
        asserted = self._assert_time.pop(exc, None)
        self.exceptions.enter(exc)
        if asserted is not None:  # from the line's assertion to the handler's first instruction
            stats.latency.append(self.cpu.count - asserted)
            if len(stats.latency) > KEEP_SAMPLES:
                del stats.latency[:KEEP_SAMPLES // 2]
        self._entry_stack.append((exc, self.cpu.count))

    def _leave(self, exc_return: int) -> None:
        exc = self.exceptions.leave(exc_return)
        entered_exc, at = self._entry_stack.pop()
        spent = self.cpu.count - at
        cycles = self._isr[entered_exc].cycles
        cycles.append(spent)
        if len(cycles) > KEEP_SAMPLES:
            del cycles[:KEEP_SAMPLES // 2]
        if len(self._entry_stack) == 0:  # outermost handler: its time includes the nested ones
            self.handler_cycles += spent
        if exc in self.nvic.pending and exc in self.nvic.asserted:
            self._assert_time.setdefault(exc, self.cpu.count)
        if not self.nvic.active and (self.scs.sleep_on_exit or self._idle_loop_at(self.cpu.pc)):
            self.sleeping = True

    def _idle_loop_at(self, pc: int) -> bool:
        """`pc` is the branch back to a WFI of an idle loop (`for (;;) __WFI();`: `wfi; b.n wfi`): the core would
        execute the branch and the WFI and sleep, so the board counts their two cycles and sleeps at once (one
        slice of the CPU fewer per interrupt)."""
        if pc in self._idle_loops:
            hit = self._idle_loops[pc]
        else:
            try:
                code = bytes(self.cpu.uc.mem_read(pc - 2, 4))
            except UcError:  # not code the board can read: no shortcut
                code = b""
            hit = code == b"\x30\xbf\xfd\xe7"  # wfi; b.n .-2
            self._idle_loops[pc] = hit
        if hit:
            self.cpu.counter.count += 2
            self.cpu.set_reg(arm.UC_ARM_REG_PC, pc)  # the wfi's successor: where the core wakes
        return hit

    def run_until(self, end: int) -> None:
        """Run the firmware until cycle `end` (at least; at most one basic block later)."""
        if self._native_core:
            self._run_until_native(end)
        elif self.SKIP_QUIET:
            self._run_until_skipping(end)
        else:
            self._run_until_every(end)

    def _run_until_native(self, end: int) -> None:
        """`run_until` in C (c/board_core.c): the skipping scheduler's steps; what the C loop hands back (a fault, an
        unmapped access, a Python error, a full sample log) is handled here as the Python scheduler does."""
        self.finish_native(end, self._core_lib.hil_core_run(self._core_ref, end, 1))

    def finish_native(self, end: int, rc: int) -> None:
        """`run_until(end)` in C after its first call into the C loop returned `rc` (the board link's period in C
        hands its run back here when it did not end cleanly)."""
        run, ref = self._core_lib.hil_core_run, self._core_ref
        try:
            while True:
                for raise_held in self._held:
                    raise_held()
                if rc == core_native.DONE:
                    return
                if rc != core_native.LOG_FULL:
                    self._native_stop(rc)
                self._drain()
                rc = run(ref, end, 0)
        finally:
            if not self._lazy_stats:
                self._drain()

    def _native_stop(self, rc: int) -> None:
        """Raise what the C loop stopped for."""
        core = self._core
        if rc == core_native.PY_ERROR:
            exc = self.cpu.take_hook_error()
            if exc is not None:
                raise exc
            raise BoardError("the board's core stopped for a Python error that left no exception")
        if rc == core_native.UC_ERROR:
            raise UcError(core.uc_error)
        if rc == core_native.INTERRUPT:
            self._interrupt(core.intno)
        elif rc == core_native.UNMAPPED:
            self._unmapped({19: "read", 20: "write", 21: "fetch"}.get(core.access, "access"), core.address)
        elif rc == core_native.BAD_RETURN:
            try:
                self.exceptions.leave(self.cpu.pc | 1)
            except ExceptionReturnError as exc:
                raise self._fault(INVPC, str(exc)) from None
        raise BoardError(f"the board's core stopped with code {rc} at {self.describe_pc()}")

    def _drain(self) -> None:
        """The C core's entries and returns since the last call into the ISR statistics."""
        core = self._core
        n = core.n_log
        if not n:
            return
        excs, kinds, values = core.log_exc, core.log_kind, core.log_value
        records = [(excs[i], kinds[i], values[i]) for i in range(n)] if n < 16 else \
            list(zip(excs[:n], kinds[:n], values[:n], strict=True))
        core.n_log = 0
        isr = self._isr
        for exc, kind, value in records:
            if kind == 0:
                stats = isr.get(exc)
                if stats is None:
                    stats = isr[exc] = IsrStats()
                stats.entries += 1
                if value >= 0:
                    samples = stats.latency
                    samples.append(value)
                    if len(samples) > KEEP_SAMPLES:
                        del samples[:KEEP_SAMPLES // 2]
            else:
                samples = isr[exc].cycles
                samples.append(value)
                if len(samples) > KEEP_SAMPLES:
                    del samples[:KEEP_SAMPLES // 2]
        self.exceptions.entries = int(core.exc_entries)

    def _active(self) -> tuple[list[Peripheral], list[Peripheral]]:
        """The models the scheduler asks at every step (outside the event group and not resting), in the board's
        order: those with an `advance`, those with a `next_event`."""
        skip = self._group_set | self._resting
        return [p for p in self._advancing if p not in skip], [p for p in self._timed if p not in skip]

    def _run_until_skipping(self, end: int) -> None:
        """`run_until` asking only the models that may have changed: the reference loop (`_run_until_every`) with
        the event group skipped while its earliest event is ahead and none of it was accessed, and the resting
        models skipped until accessed. A skipped model's `advance` would do nothing and its `next_event` would
        answer the same, so the steps, slices and records are the reference's."""
        nvic, counter = self.nvic, self.cpu.counter
        pending = nvic.pending
        systick, advancing, timed_set = self.scs.systick, self._advancing, self._timed_set
        group_set, resting, woken = self._group_set, self._resting, self._woken
        group_timed = [p for p in self._group if p in timed_set]
        # on entry every model is asked again (its owner may have changed any of them between two calls)
        self._group_touched = True
        woken.update(self._may_rest)
        active_adv, active_timed = self._active()
        settled = self._settled_at
        while True:
            now: int = counter.count
            group_due = self._group_due
            hot = self._group_touched or (group_due is not None and group_due <= now)
            if now != settled:
                systick.advance(now)
                if hot or woken:
                    for p in advancing:
                        if (p in group_set and not hot) or (p in resting and p not in woken):
                            continue
                        p.advance(now)
                else:
                    for p in active_adv:
                        p.advance(now)
            settled = -1
            if now >= end:
                self._settled_at = now
                return
            if pending and self._take_pending():
                continue
            if woken:  # accessed resting models: resting still, or asked at every step again
                for p in woken:
                    if p.quiet():  # type: ignore[attr-defined]
                        resting.add(p)
                    else:
                        resting.discard(p)
                woken.clear()
                active_adv, active_timed = self._active()
            event = systick.next_event(now)
            for p in active_timed:
                at = p.next_event(now)
                if at is not None and (event is None or at < event):
                    event = at
            if hot or self._group_touched:
                self._group_touched = False
                group_due = None
                for p in group_timed:
                    at = p.next_event(now)
                    if at is not None and (group_due is None or at < group_due):
                        group_due = at
                self._group_due = group_due
            if group_due is not None and (event is None or group_due < event):
                event = group_due
            self._sleep_or_run(now, end, event)

    def _run_until_every(self, end: int) -> None:
        """`run_until` asking every model at every step (the reference)."""
        nvic, counter = self.nvic, self.cpu.counter
        pending = nvic.pending
        systick, advancing, timed = self.scs.systick, self._advancing, self._timed
        settled = self._settled_at  # the models are up to this cycle already (the last call ended there)
        while True:
            now: int = counter.count
            # every model up to now (inline: this loop runs several times per period)
            if now != settled:
                systick.advance(now)
                for p in advancing:
                    p.advance(now)
            settled = -1
            if now >= end:
                self._settled_at = now
                return
            if pending and self._take_pending():
                continue
            # the earliest event of a model or SysTick after now (next_event, inline)
            event = systick.next_event(now)
            for p in timed:
                at = p.next_event(now)
                if at is not None and (event is None or at < event):
                    event = at
            self._sleep_or_run(now, end, event)

    def _take_pending(self) -> bool:
        """Enter the pending exception that preempts now under PRIMASK/BASEPRI, if any (waking a WFI): True when one
        was entered."""
        primask, basepri = self._masks()
        take = self.nvic.preempting(primask, basepri)
        if take is None:
            return False
        self.sleeping = False
        self._enter(take)
        return True

    def _sleep_or_run(self, now: int, end: int, event: int | None) -> None:
        """One step of `run_until` from cycle `now`: asleep (WFI), skip to the earliest of `event` and `end` unless a
        pending interrupt wakes the core; awake, run the core up to that cycle (held off by MASKED_SLICE while an
        enabled interrupt is pending but masked)."""
        nvic = self.nvic
        pending = nvic.pending
        if self.sleeping:
            if pending and nvic.preempting(False, self._masks()[1]) is not None:  # WFI wakes with PRIMASK
                self.sleeping = False
            else:
                until = end if event is None else min(event, end)
                self.sleep_cycles += until - now
                self.cpu.counter.count = until
                return
        limit = end if event is None else min(event, end)
        if pending and any(nvic.enabled[e] for e in pending):  # held off: see MASKED_SLICE
            limit = min(limit, now + MASKED_SLICE)
        self._slice(max(limit, now + 1))

    def _slice(self, limit: int) -> None:
        cpu = self.cpu
        stop = cpu.run(cpu.pc, limit)
        if stop.kind == "limit":
            return
        if stop.kind == "exc_return":
            pc = cpu.pc | 1
            try:
                self._leave(pc)
            except ExceptionReturnError as exc:
                raise self._fault(INVPC, str(exc)) from None
        elif stop.kind == "sleep":
            self.sleeping = True
        elif stop.kind == "interrupt":
            self._interrupt(stop.intno)
        elif stop.kind == "unmapped":
            self._unmapped(stop.access, stop.address)

    def _unmapped(self, access: str, address: int) -> None:
        """Raise the error of an access to unmapped memory."""
        if (0x4000_0000 <= address < 0x6000_0000 or address >= 0xE000_0000) and access != "fetch":
            raise self._unmodelled(address, access)
        if access == "fetch":
            raise self._fault(IBUSERR, f"instruction fetch from {address:#010x}")
        self.scs.bfar = address
        raise self._fault(PRECISERR | BFARVALID, f"{access} of unmapped address {address:#010x}")

    def _interrupt(self, intno: int) -> None:
        if intno == EXCP_SWI:
            self.nvic.pending.add(SVCALL)
            return
        if intno == EXCP_BKPT:
            raise BoardError(f"the firmware executed BKPT at {self.describe_pc()} (no debugger on the virtual board)")
        bits = {EXCP_UDEF: UNDEFINSTR, EXCP_NOCP: NOCP, EXCP_INVSTATE: INVSTATE, EXCP_UNALIGNED: UNALIGNED,
                EXCP_DIVBYZERO: DIVBYZERO}.get(intno)
        if bits is None:
            raise BoardError(f"CPU exception {intno} of the emulator at {self.describe_pc()}")
        raise self._fault(bits)

    def _fault(self, cfsr_bits: int, detail: str = "") -> BoardFaultError:
        """The fault report (the board stops: the firmware's own fault handler is not run)."""
        self.scs.cfsr |= cfsr_bits
        self.scs.hfsr |= FORCED
        pc, lr = self.cpu.pc, self.cpu.reg(arm.UC_ARM_REG_LR)
        return BoardFaultError(HARDFAULT, pc, lr, self.scs.cfsr, self.scs.hfsr, self.scs.bfar, self.scs.mmfar, self.elf,
                          detail)

    def symbol(self, name: str) -> int | None:
        """Address of a symbol of the firmware (None when it has none by that name)."""
        if self._symbols is None:
            self._symbols = elf_symbols(self.elf)
        return self._symbols.get(name)
