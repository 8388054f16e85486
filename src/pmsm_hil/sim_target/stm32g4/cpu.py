"""The Cortex-M4F core of the virtual board on Unicorn: the part's memories (flash with its boot alias at 0,
SRAM, CCM-SRAM and its alias), the native instruction counter that bounds each slice, and why a slice ended.

Unicorn has no NVIC: the core runs in Thread mode as far as Unicorn knows, and the board enters and leaves
exceptions itself (src/pmsm_hil/sim_target/stm32g4/nvic.py). A branch to an EXC_RETURN value (0xFFFFFFxx) ends the
slice (QEMU's M-profile magic addresses), so does WFI/WFE. Peripheral pages are Unicorn MMIO regions: only their
accesses run Python, never the code between them.
"""

from __future__ import annotations

import ctypes
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

from unicorn import (
    UC_ARCH_ARM,
    UC_ERR_EXCEPTION,
    UC_ERR_FETCH_PROT,
    UC_HOOK_BLOCK,
    UC_HOOK_INTR,
    UC_HOOK_MEM_FETCH_UNMAPPED,
    UC_HOOK_MEM_READ_UNMAPPED,
    UC_HOOK_MEM_WRITE_UNMAPPED,
    UC_HOOK_TLB_FILL,
    UC_MODE_MCLASS,
    UC_MODE_THUMB,
    UC_PROT_ALL,
    UC_PROT_READ,
    UC_PROT_WRITE,
    UC_TLB_VIRTUAL,
    Uc,
    UcError,
)
from unicorn import arm_const as arm
from unicorn.unicorn_py3.unicorn import MMIO_READ_CFUNC, MMIO_WRITE_CFUNC, uclib

from pmsm_hil.sim_target.stm32g4.counter import REGIONS, CounterState, hook_function, tlb_fill_function
from pmsm_hil.sim_target.stm32g4.part import CCM_BASE, FLASH_BASE, SRAM_BASE, Part

PAGE = 0x1000
#: QEMU's internal exception numbers (target/arm/cpu.h) that reach the interrupt hook
EXCP_UDEF, EXCP_SWI, EXCP_PREFETCH_ABORT, EXCP_BKPT, EXCP_EXCEPTION_EXIT = 1, 2, 3, 7, 8
EXCP_NOCP, EXCP_INVSTATE, EXCP_UNALIGNED, EXCP_DIVBYZERO = 17, 18, 22, 23
WFI, WFE = 0xBF30, 0xBF20

#: r0-r3, r12, lr, pc, xpsr: the basic exception frame, in stack order
FRAME_REGS = (arm.UC_ARM_REG_R0, arm.UC_ARM_REG_R1, arm.UC_ARM_REG_R2, arm.UC_ARM_REG_R3, arm.UC_ARM_REG_R12,
              arm.UC_ARM_REG_LR, arm.UC_ARM_REG_PC, arm.UC_ARM_REG_XPSR)
FP_REGS = (*tuple(getattr(arm, f"UC_ARM_REG_S{i}") for i in range(16)), arm.UC_ARM_REG_FPSCR)


class RegBatch:
    """A fixed list of 32-bit registers with the C arrays uc_reg_read_batch / uc_reg_write_batch take (the values
    as uint32: what Unicorn's Arm registers read and write, so no masking on the way in or out)."""

    def __init__(self, ids: Sequence[int]) -> None:
        self.count = len(ids)
        self.ids = (ctypes.c_int * self.count)(*ids)
        self.values = (ctypes.c_uint32 * self.count)()
        self.ptrs = (ctypes.c_void_p * self.count)(
            *(ctypes.addressof(self.values) + 4 * i for i in range(self.count)))


def _round_page(n: int) -> int:
    return (n + PAGE - 1) // PAGE * PAGE


@dataclass(slots=True)
class Stop:
    """Why a slice ended: `kind` is "limit" (the count reached the slice's end, or a peripheral asked for a new
    schedule), "exc_return", "sleep" (WFI/WFE executed), "interrupt" (an SVC, BKPT or CPU exception: `intno`),
    "unmapped" (`access`, `address`)."""

    kind: str
    intno: int = 0
    access: str = ""
    address: int = 0


MmioRead = Callable[[int, int], int]
MmioWrite = Callable[[int, int, int], None]


class Cpu:
    """Unicorn set up as the part's Cortex-M4F with its memories mapped; `run` executes one slice."""

    #: the instruction counter keeps the count of each flash block it decoded (c/insn_count.c) instead of decoding
    #: the block at every execution (the reference)
    COUNT_CACHE = True
    #: SRAM and CCM-SRAM mapped without execute permission until the core first fetches from them: Unicorn then
    #: skips the translated-code check of every store to them (its notdirty path). The first fetch stops the core
    #: (UC_ERR_FETCH_PROT) before any instruction there ran; `grant_ram_exec` makes them executable and the slice
    #: is run again from the same pc. False: mapped executable from the start (the reference).
    LAZY_RAM_EXEC = True
    #: Unicorn's virtual TLB with the board's fill (c/insn_count.c, hil_counter_tlb_fill: the Armv7-M default memory
    #: map, as the CPU's own fill with the MPU off) instead of the CPU's: an SRAM page written while no code ran from
    #: the SRAMs loses its slow-store flag at its first store. The stop-on-unmapped hooks then leave the SRAMs out
    #: (Unicorn keeps the flag of a page a memory hook covers). A fetch from an execute-never region stops the core
    #: as the CPU's prefetch abort does (interrupt 3). False: the CPU's TLB fill (the reference).
    VIRTUAL_TLB = True

    def __init__(self, part: Part, *, python_stops: bool = True) -> None:
        """`python_stops` False: the slice's stops (interrupts, unmapped accesses) are left to hooks the board's C
        core registers (`run` is then not used)."""
        self.part = part
        uc: Any = Uc(UC_ARCH_ARM, UC_MODE_THUMB | UC_MODE_MCLASS)
        uc.ctl_set_cpu_model(arm.UC_CPU_ARM_CORTEX_M4)
        self.uc = uc
        self.flash = (ctypes.c_uint8 * part.flash_size)()
        ctypes.memset(self.flash, 0xFF, part.flash_size)  # erased flash
        uc.mem_map_ptr(FLASH_BASE, part.flash_size, UC_PROT_READ | 4, self.flash)  # read + exec
        uc.mem_map_ptr(0, part.flash_size, UC_PROT_READ | 4, self.flash)  # boot from main flash: aliased at 0
        sram_span = _round_page(part.sram_size + part.ccm_size)
        ccm_span = _round_page(part.ccm_size)
        self.sram = (ctypes.c_uint8 * (part.sram_size + ccm_span + PAGE))()
        #: 1 once the SRAMs are executable (see LAZY_RAM_EXEC; the board's C core sets it too)
        self.ram_exec = ctypes.c_int32(0 if self.LAZY_RAM_EXEC else 1)
        ram_prot = UC_PROT_ALL if self.ram_exec.value else UC_PROT_READ | UC_PROT_WRITE
        #: the SRAM (with CCM-SRAM's alias) and CCM-SRAM: (base, span)
        self.ram = ((SRAM_BASE, sram_span), (CCM_BASE, ccm_span))
        uc.mem_map_ptr(SRAM_BASE, sram_span, ram_prot, self.sram)
        ccm_ptr = ctypes.cast(ctypes.addressof(self.sram) + part.sram_size, ctypes.c_void_p).value
        uc.mem_map_ptr(CCM_BASE, ccm_span, ram_prot, ccm_ptr)
        self.extra_ram: list[Any] = []
        self.counter = CounterState()
        self.counter.limit = 1 << 63
        self.counter.stop = ctypes.cast(uclib.uc_emu_stop, ctypes.c_void_p).value
        regions = [(FLASH_BASE, part.flash_size, ctypes.addressof(self.flash)),
                   (0, part.flash_size, ctypes.addressof(self.flash)),
                   (SRAM_BASE, sram_span, ctypes.addressof(self.sram)),
                   (CCM_BASE, ccm_span, ccm_ptr or 0)]
        for i, (base, size, host) in enumerate(regions[:REGIONS]):
            self.counter.base[i], self.counter.size[i], self.counter.host[i] = base, size, host
        self.counter.n_regions = len(regions)
        self.counter.n_fixed = 2 if self.COUNT_CACHE else 0  # the flash and its alias
        self._fixed = regions[:2]
        self._hook = ctypes.c_size_t()
        status = uclib.uc_hook_add(uc._uch, ctypes.byref(self._hook), UC_HOOK_BLOCK,
                                   ctypes.c_void_p(hook_function()), ctypes.cast(ctypes.pointer(self.counter),
                                                                                 ctypes.c_void_p),
                                   ctypes.c_uint64(1), ctypes.c_uint64(0))
        if status != 0:
            raise UcError(status)
        self.counter.ram_exec = ctypes.addressof(self.ram_exec)
        for i, (base, span) in enumerate(self.ram):
            self.counter.ram_base[i], self.counter.ram_span[i] = base, span
        if self.VIRTUAL_TLB:
            uc.ctl_set_tlb_mode(UC_TLB_VIRTUAL)
            self._tlb_hook = ctypes.c_size_t()
            status = uclib.uc_hook_add(uc._uch, ctypes.byref(self._tlb_hook), UC_HOOK_TLB_FILL,
                                       ctypes.c_void_p(tlb_fill_function()),
                                       ctypes.c_void_p(ctypes.addressof(self.counter)), ctypes.c_uint64(1),
                                       ctypes.c_uint64(0))
            if status != 0:
                raise UcError(status)
        self._stop: Stop | None = None
        self._uch = uc._uch
        self._reg_buf = ctypes.c_uint64(0)
        self._reg_ref = ctypes.byref(self._reg_buf)
        self._mmio_callbacks: list[tuple[Any, Any]] = []
        self._word = (ctypes.c_char * 4)()
        #: set to 1 by an MMIO callback that raised (its exception is the binding's `_hook_exception`): the board's C
        #: core checks it after each slice
        self.hook_error = ctypes.c_int32(0)
        if python_stops:
            uc.hook_add(UC_HOOK_INTR, self._on_interrupt)
            for begin, end in self.unmapped_ranges():
                uc.hook_add(UC_HOOK_MEM_READ_UNMAPPED | UC_HOOK_MEM_WRITE_UNMAPPED | UC_HOOK_MEM_FETCH_UNMAPPED,
                            self._on_unmapped, begin=begin, end=end)

    def unmapped_ranges(self) -> list[tuple[int, int]]:
        """The [begin, end] ranges the stop-on-unmapped hooks cover: everything (1, 0) with the CPU's TLB, all but
        the SRAMs with the virtual one (nothing there is unmapped)."""
        if not self.VIRTUAL_TLB:
            return [(1, 0)]
        out, at = [], 0
        for base, span in sorted(self.ram):
            out.append((at, base - 1))
            at = base + span
        return [*out, (at, 0xFFFF_FFFF_FFFF_FFFF)]

    # --- memory -------------------------------------------------------------------------------------------------

    def map_ram(self, base: int, size: int) -> None:
        """Plain RAM at `base` (a peripheral's own SRAM, e.g. the FDCAN message RAM), page-rounded."""
        start, end = base & ~(PAGE - 1), _round_page(base + size)
        buf = (ctypes.c_uint8 * (end - start))()
        self.uc.mem_map_ptr(start, end - start, UC_PROT_READ | 2, buf)
        self.extra_ram.append(buf)

    def map_mmio(self, base: int, size: int, read: MmioRead, write: MmioWrite, *,
                 native_read: tuple[int, Any] | None = None, native_write: tuple[int, Any] | None = None) -> None:
        """Route every access to [base, base + size) to `read(address, size)` / `write(address, size, value)`.
        The callbacks are Unicorn's C callbacks straight (not the binding's layered wrappers); an exception in
        one stops the core and is raised by `run`, as the binding does. `native_read` (a C uc_cb_mmio_read_t's
        address and its state, a ctypes Structure whose `fallback` field it calls for what it does not handle)
        takes the reads instead, `read` as its fallback; `native_write` (a uc_cb_mmio_write_t and its state, whose
        `fallback_write` field it calls) the writes, `write` as its fallback."""
        uch = self._uch

        def on_read(_handle: int, offset: int, nbytes: int, _user: int) -> int:
            try:
                return read(base + offset, nbytes)
            except BaseException as exc:  # re-raised by run() once the core stopped
                self.hook_failed(exc)
                return 0

        def on_write(_handle: int, offset: int, nbytes: int, value: int, _user: int) -> None:
            try:
                write(base + offset, nbytes, value)
            except BaseException as exc:  # re-raised by run() once the core stopped
                self.hook_failed(exc)

        read_fn, write_fn = MMIO_READ_CFUNC(on_read), MMIO_WRITE_CFUNC(on_write)
        self._mmio_callbacks.append((read_fn, write_fn))
        user: int | None = None
        if native_read is not None:
            function, state = native_read
            state.fallback = ctypes.cast(read_fn, ctypes.c_void_p).value
            self._mmio_callbacks.append((MMIO_READ_CFUNC(function), state))
            read_fn, user = self._mmio_callbacks[-1][0], ctypes.addressof(state)
        write_user: int | None = None
        if native_write is not None:
            function, state = native_write
            state.fallback_write = ctypes.cast(write_fn, ctypes.c_void_p).value
            self._mmio_callbacks.append((MMIO_WRITE_CFUNC(function), state))
            write_fn, write_user = self._mmio_callbacks[-1][0], ctypes.addressof(state)
        status = uclib.uc_mmio_map(uch, base, size, read_fn, user, write_fn, write_user)
        if status != 0:
            raise UcError(status)

    def grant_ram_exec(self, error: int) -> bool:
        """A slice ended with Unicorn's `error`: if it is the first fetch from the SRAMs (LAZY_RAM_EXEC), make them
        executable and say so (run the slice again from the pc, where the core stopped before the fetch)."""
        if error != UC_ERR_FETCH_PROT or self.ram_exec.value:
            return False
        pc = self.pc
        if not any(base <= pc < base + span for base, span in self.ram):
            return False
        for base, span in self.ram:
            self.uc.mem_protect(base, span, UC_PROT_ALL)
        self.ram_exec.value = 1
        return True

    def hook_failed(self, exc: BaseException) -> None:
        """A callback of the running core raised `exc`: keep it (the first one) for the caller and stop the core."""
        if self.uc._hook_exception is None:
            self.uc._hook_exception = exc
        self.hook_error.value = 1
        uclib.uc_emu_stop(self._uch)

    def take_hook_error(self) -> BaseException | None:
        """The exception a callback raised since the last call (None: none), cleared."""
        exc = self.uc._hook_exception
        self.uc._hook_exception = None
        self.hook_error.value = 0
        return exc  # type: ignore[no-any-return]

    def load(self, address: int, data: bytes) -> None:
        """Program bytes into flash or RAM (ELF loading)."""
        self.uc.mem_write(address, data)
        self._code_written(address, len(data))

    def _code_written(self, address: int, size: int) -> None:
        """Bytes at [address, address + size) were written: the counter forgets its decoded blocks if they may
        hold some of them (the flash or its alias)."""
        if any(address < base + span and base < address + size for base, span, _ in self._fixed):
            self.counter.forget_blocks()

    def read_u32(self, address: int) -> int:
        status = uclib.uc_mem_read(self._uch, address, self._word, 4)
        if status != 0:
            raise UcError(status)
        return int.from_bytes(self._word.raw, "little")

    def write_bytes(self, address: int, data: bytes) -> None:
        """Store `data` at `address` through the core (uc_mem_write, without the binding's layers)."""
        status = uclib.uc_mem_write(self._uch, address, data, len(data))
        if status != 0:
            raise UcError(status)
        self._code_written(address, len(data))

    def read_bytes(self, address: int, size: int) -> bytes:
        buf = ctypes.create_string_buffer(size)
        status = uclib.uc_mem_read(self._uch, address, buf, size)
        if status != 0:
            raise UcError(status)
        return buf.raw

    # --- registers ----------------------------------------------------------------------------------------------

    def reg(self, reg: int) -> int:
        """A 32-bit register, through the C API (the binding's reg_read costs microseconds)."""
        uclib.uc_reg_read(self._uch, reg, self._reg_ref)
        return int(self._reg_buf.value) & 0xFFFF_FFFF

    def set_reg(self, reg: int, value: int) -> None:
        self._reg_buf.value = value & 0xFFFFFFFF
        uclib.uc_reg_write(self._uch, reg, self._reg_ref)

    def regs(self, regs: RegBatch) -> list[int]:
        """Several 32-bit registers in one call (uc_reg_read_batch)."""
        uclib.uc_reg_read_batch(self._uch, regs.ids, regs.ptrs, regs.count)
        return regs.values[:]

    def set_regs(self, regs: RegBatch, values: Sequence[int]) -> None:
        """Several 32-bit registers in one call (uc_reg_write_batch)."""
        regs.values[:] = [v & 0xFFFF_FFFF for v in values]
        uclib.uc_reg_write_batch(self._uch, regs.ids, regs.ptrs, regs.count)

    @property
    def pc(self) -> int:
        return self.reg(arm.UC_ARM_REG_PC)

    # --- running ------------------------------------------------------------------------------------------------

    @property
    def count(self) -> int:
        """Instructions begun since reset."""
        return int(self.counter.count)

    def request_stop(self) -> None:
        """End the slice at the next block boundary (a peripheral changed the schedule). Never `emu_stop` inside
        an access: Unicorn would restart the accessing instruction and repeat its store."""
        self.counter.limit = self.counter.count

    def run(self, pc: int, limit: int) -> Stop:
        """Execute from `pc` until the instruction count reaches `limit` (at a block's end) or something stops the
        core; a hook's exception (a BoardError of a peripheral access) propagates."""
        self._stop = None
        self.hook_error.value = 0
        self.counter.limit = limit
        begun = self.counter.count
        try:
            try:
                self.uc.emu_start(pc | 1, 0xFFFF_FFFF_FFFF)
            except UcError as exc:
                if self._stop is not None or not self.grant_ram_exec(exc.errno):
                    raise
                self.uc.emu_start(self.pc | 1, 0xFFFF_FFFF_FFFF)  # nothing ran at the pc: the same slice goes on
        except UcError as exc:
            if self._stop is None and exc.errno == UC_ERR_EXCEPTION:  # the virtual TLB refused a fetch
                self._stop = Stop("interrupt", intno=EXCP_PREFETCH_ABORT)
            if self._stop is None:
                raise
        stop = self._stop
        if stop is not None:
            return stop
        now_pc = self.pc
        if now_pc >= 0xFFFF_FF00:
            return Stop("exc_return")
        if self.counter.count > begun and now_pc >= 2:
            try:
                before = int.from_bytes(self.read_bytes(now_pc - 2, 2), "little")
            except UcError:
                before = 0
            if before in (WFI, WFE):
                return Stop("sleep")
        return Stop("limit")

    def _on_interrupt(self, uc: Uc, intno: int, _: object) -> None:
        self._stop = Stop("exc_return" if intno == EXCP_EXCEPTION_EXIT else "interrupt", intno=intno)
        uc.emu_stop()

    def _on_unmapped(self, uc: Uc, access: int, address: int, size: int, value: int, _: object) -> bool:
        kind = {19: "read", 20: "write", 21: "fetch"}.get(access, "access")
        if kind == "fetch" and address >= 0xFFFF_FF00:
            self._stop = Stop("exc_return")
        else:
            self._stop = Stop("unmapped", access=kind, address=address)
        return False
