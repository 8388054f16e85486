"""FDCAN1 of the STM32G474 (RM0440 "FD controller area network"): registers at 0x40006400, message RAM in SRAMCAN at
0x4000A400, interrupt lines FDCAN1_IT0 (IRQ 21) and FDCAN1_IT1 (IRQ 22).

The firmware configures the controller through the registers and moves frames through the message RAM, which the
model reads and writes with `BoardBus.read_memory`/`write_memory`. The run side hands it received frames with
`deliver` and collects the frames the firmware sent with `take_transmitted`. A transmission occupies the bus for
the frame's bits (dynamic stuff bits left out) at the bit rates of NBTP/DBTP; the bus is otherwise error-free.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import can

from pmsm_hil.sim_target.stm32g4.peripherals import fdcan_filter as flt
from pmsm_hil.sim_target.stm32g4.peripherals import fdcan_ram as ram
from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError, Peripheral, register

# Register offsets (RM0440 FDCAN register map)
CREL, ENDN, DBTP, TEST, RWD, CCCR, NBTP, TSCC, TSCV, TOCC, TOCV = (
    0x000, 0x004, 0x00C, 0x010, 0x014, 0x018, 0x01C, 0x020, 0x024, 0x028, 0x02C)
ECR, PSR, TDCR, IR, IE, ILS, ILE = 0x040, 0x044, 0x048, 0x050, 0x054, 0x058, 0x05C
RXGFC, XIDAM, HPMS, RXF0S, RXF0A, RXF1S, RXF1A = 0x080, 0x084, 0x088, 0x090, 0x094, 0x098, 0x09C
TXBC, TXFQS, TXBRP, TXBAR, TXBCR, TXBTO, TXBCF, TXBTIE, TXBCIE, TXEFS, TXEFA = (
    0x0C0, 0x0C4, 0x0C8, 0x0CC, 0x0D0, 0x0D4, 0x0D8, 0x0DC, 0x0E0, 0x0E4, 0x0E8)
CKDIV = 0x100

REGISTER_NAMES = {
    CREL: "CREL", ENDN: "ENDN", DBTP: "DBTP", TEST: "TEST", RWD: "RWD", CCCR: "CCCR", NBTP: "NBTP", TSCC: "TSCC",
    TSCV: "TSCV", TOCC: "TOCC", TOCV: "TOCV", ECR: "ECR", PSR: "PSR", TDCR: "TDCR", IR: "IR", IE: "IE", ILS: "ILS",
    ILE: "ILE", RXGFC: "RXGFC", XIDAM: "XIDAM", HPMS: "HPMS", RXF0S: "RXF0S", RXF0A: "RXF0A", RXF1S: "RXF1S",
    RXF1A: "RXF1A", TXBC: "TXBC", TXFQS: "TXFQS", TXBRP: "TXBRP", TXBAR: "TXBAR", TXBCR: "TXBCR", TXBTO: "TXBTO",
    TXBCF: "TXBCF", TXBTIE: "TXBTIE", TXBCIE: "TXBCIE", TXEFS: "TXEFS", TXEFA: "TXEFA", CKDIV: "CKDIV",
}

# CCCR bits
INIT, CCE, ASM, CSA, CSR, MON, DAR, TEST_EN, FDOE, BRSE = (1 << b for b in (0, 1, 2, 3, 4, 5, 6, 7, 8, 9))
CCCR_PROTECTED = ASM | MON | DAR | TEST_EN | FDOE | BRSE | (1 << 12) | (1 << 13) | (1 << 14) | (1 << 15)
TEST_LBCK = 1 << 4

# IR bits
RF0N, RF0F, RF0L, RF1N, RF1F, RF1L, HPM, TC, TCF, TFE, TEFN, TEFF, TEFL, TSW = (1 << b for b in range(14))
IR_MASK = (1 << 24) - 1
#: ILS bit -> the IR bits of that group (RXFIFO0, RXFIFO1, SMSG, TFERR, MISC, BERR, PERR)
ILS_GROUPS = (0x7, 0x7 << 3, 0x7 << 6, 0xF << 9, 0x7 << 13, 0x3 << 16, 0x3F << 18)
#: ILS value -> the IR bits it routes to IT1
ILS_LINE1 = tuple(sum(group for bit, group in enumerate(ILS_GROUPS) if ils & (1 << bit)) for ils in range(128))

# Writable bits of the plain stored registers; the protected ones change only with CCCR.INIT and CCCR.CCE set
WRITABLE = {
    DBTP: 0x009F_1FFF, NBTP: 0xFFFF_FF7F, TDCR: 0x7F7F, TSCC: 0x000F_0003, TOCC: 0xFFFF_0007, RWD: 0xFF,
    RXGFC: 0x0F1F_033F, XIDAM: 0x1FFF_FFFF, TXBC: 1 << 24, CKDIV: 0xF, TEST: 0x70,
    IE: IR_MASK, ILS: 0x7F, ILE: 0x3, TXBTIE: 0x7, TXBCIE: 0x7,
}
PROTECTED = frozenset({DBTP, NBTP, TDCR, TSCC, TOCC, RWD, RXGFC, XIDAM, TXBC, CKDIV})
RESET_VALUES = {DBTP: 0x0000_0A33, NBTP: 0x0600_0A03, TOCC: 0xFFFF_0000, XIDAM: 0x1FFF_FFFF}

#: registers that read a fixed value: core release 3.2.1 of 2018-12-14, endianness pattern, an error-free ECR,
#: the timeout counter at its reset value, the write-only acknowledge and request registers
CONSTANT_READS = {CREL: 0x3214_1218, ENDN: 0x8765_4321, ECR: 0, TOCV: 0xFFFF, TXBAR: 0, RXF0A: 0, RXF1A: 0,
                  TXEFA: 0}
PSR_RESET = 0x707  # LEC and DLEC 7: no change since the last read


@dataclass
class _Ring:
    """A hardware FIFO of 3 elements: get index, put index, fill level."""

    get: int = 0
    put: int = 0
    fill: int = 0

    def push(self) -> int:
        """Take the element at the put index; returns it."""
        index = self.put
        self.put = (self.put + 1) % 3
        self.fill += 1
        return index

    def acknowledge(self, index: int) -> None:
        """The firmware read up to `index`: get index to index + 1, fill level down by the elements passed (an
        index outside the filled part changes nothing)."""
        count = (index - self.get) % 3 + 1
        if index < 3 and count <= self.fill:
            self.get = (index + 1) % 3
            self.fill -= count


@dataclass
class _InFlight:
    """The TX buffer on the bus: its frame, event request and marker, start and end of frame [cycle]."""

    buffer: int
    element: ram.Element
    header: ram.TxHeader
    start: int
    end: int
    cancel: bool = False


@runtime_checkable
class _KernelClock(Protocol):
    def fdcan_kernel_clock(self, now: int) -> tuple[int, str]: ...


@register("FDCAN1")
class Fdcan(Peripheral):
    """One FDCAN instance; FDCAN1's addresses and interrupt lines."""

    base = 0x4000_6400
    size = 0x400
    ram_base = ram.SRAMCAN_BASE
    irq_lines = (21, 22)
    #: the FDCAN kernel clock [Hz]: RCC CCIPR.FDCANSEL's source when the firmware takes the controller out of
    #: initialisation (on a board with an RCC model); None: SYSCLK (a bare bus without one)
    kernel_clock_hz: int | None = None
    #: the bus's (nominal, data) bit rates [bit/s] the run states (None: not stated, not checked)
    link_bitrates: tuple[int | None, int | None] = (None, None)
    #: relative bit-rate difference to the run's link tolerated (CAN's oscillator tolerance is of this order)
    BITRATE_TOLERANCE = 0.005
    #: a frame's end and the timestamp counter's wrap are its only events; `deliver` reports itself
    EVENT_DRIVEN = True
    #: called when a frame joins `transmitted` or CCCR is written (the board link's period in C then hands the
    #: period to Python), or None
    on_change: Callable[[], None] | None = None

    def reset(self) -> None:
        self.regs = {offset: RESET_VALUES.get(offset, 0) for offset in WRITABLE}
        self.cccr = INIT
        self.ir = 0
        self.hpms = 0
        self.rx = (_Ring(), _Ring())
        self.tef = _Ring()
        self.tx_fifo = _Ring()
        self.txbrp = 0
        self.txbto = 0
        self.txbcf = 0
        self.in_flight: _InFlight | None = None
        self.psr = PSR_RESET
        self.ts_origin = 0
        self.ts_offset = 0
        self.ts_wraps = 0
        #: the enabled IR flags that hold each line (IT0, IT1) up
        self.line_flags = [0, 0]
        self.transmitted: list[can.Message] = []
        #: writes the chip ignored: protected registers outside INIT+CCE (count)
        self.ignored_writes = 0
        #: frames `deliver` handed over that the controller could not take, by reason
        self.rx_dropped: dict[str, int] = {}

    # ----- the run side
    def deliver(self, frame: can.Message, now: int) -> None:
        """A frame from the bus, received completely at cycle `now`: filtered, stored in RX FIFO 0/1 (or counted
        lost when that FIFO is full in blocking mode), its interrupts raised. BoardError for a frame no CAN
        controller could receive (an identifier or payload length its format cannot carry)."""
        self.inputs_changed()
        self.advance(now)
        if frame.is_error_frame:
            self._drop("error frame")
            return
        element = self._element_of(frame)
        if self.cccr & INIT:
            self._drop("not synchronised (CCCR.INIT set)")
        elif element.fd and not self.cccr & FDOE:
            self._drop("CAN FD frame with CCCR.FDOE clear")
        else:
            self._receive(element, now)
        self._update_lines()

    def take_transmitted(self) -> list[can.Message]:
        """The frames the firmware sent since the last call, in bus order; `timestamp` is the end of the frame
        [s] (its cycle over SYSCLK)."""
        frames, self.transmitted = self.transmitted, []
        return frames

    def frame_cycles(self, frame: can.Message) -> int:
        """CPU cycles `frame` takes on the bus at the bit rates the firmware configured (dynamic stuff bits left
        out), for a run side that delivers a frame at its end: sent at cycle t, it arrives at t + this."""
        return self._frame_cycles(self._element_of(frame))

    def line_active(self, line: int) -> bool:
        """Whether interrupt line `line` (0: IT0, 1: IT1) is asserted now (an enabled flag in a group routed to
        it and ILE.EINTx set), for an NVIC that re-pends a level-sensitive line at exception return."""
        return self.line_state[line]

    # ----- Peripheral
    def next_event(self, now: int) -> int | None:
        events = []
        if self.in_flight is not None:
            events.append(self.in_flight.end)
        wrap = self._next_wrap()
        if wrap is not None:
            events.append(wrap)
        return min(events) if events else None

    def advance(self, now: int) -> None:
        while self.in_flight is not None and self.in_flight.end <= now:
            end = self.in_flight.end
            self._complete(end)
            self._start_next(end)
        if self._timestamp_units(now) >> 16 > self.ts_wraps:
            self.ts_wraps = self._timestamp_units(now) >> 16
            self.ir |= TSW
        self._update_lines()

    def read(self, offset: int, size: int, now: int) -> int:
        reg, shift = self._locate(offset, size, "read")
        self.advance(now)
        return (self._read_register(reg, now) >> shift) & ((1 << 8 * size) - 1)

    def write(self, offset: int, size: int, value: int, now: int) -> None:
        reg, shift = self._locate(offset, size, "write")
        self.advance(now)
        mask = ((1 << 8 * size) - 1) << shift
        self._write_register(reg, (value << shift) & mask, mask, now)
        self._update_lines()

    # ----- registers
    def _locate(self, offset: int, size: int, access: str) -> tuple[int, int]:
        reg = offset & ~3
        if size not in (1, 2, 4) or (offset & 3) + size > 4:
            raise BoardError(f"{self.name}: {size}-byte {access} at offset 0x{offset:03X} crosses a register")
        if reg not in REGISTER_NAMES:
            raise BoardError(f"{self.name}: {access} of reserved offset 0x{offset:03X} "
                             f"(address 0x{self.base + offset:08X}); RM0440 has no register there")
        return reg, (offset & 3) * 8

    def _read_register(self, reg: int, now: int) -> int:
        if reg in self.regs:
            value = self.regs[reg]
            if reg == TEST:
                value |= 0x80  # RX pin: the bus is recessive between frames
            return value
        if reg == CCCR:
            return self.cccr
        if reg == PSR:
            value = self.psr | (self._activity() << 3)
            self.psr = (self.psr & ~0x7F07) | 0x707  # LEC, DLEC back to 7, RESI/RBRS/REDL/PXE cleared on read
            return value
        if reg == IR:
            return self.ir
        if reg in (RXF0S, RXF1S):
            return self._fifo_status(0 if reg == RXF0S else 1)
        if reg == TXFQS:
            return self._txfqs()
        if reg == TXBRP:
            return self.txbrp
        if reg == TXBTO:
            return self.txbto
        if reg == TXBCF:
            return self.txbcf
        if reg == TXBCR:
            return self._cancel_pending()
        if reg == TXEFS:
            return self._ring_status(self.tef, bool(self.ir & TEFL))
        if reg == HPMS:
            return self.hpms
        if reg == TSCV:
            return self._timestamp(now)
        return CONSTANT_READS[reg]

    def _write_register(self, reg: int, value: int, mask: int, now: int) -> None:
        if reg == CCCR:
            self._write_cccr((self.cccr & ~mask) | value, now)
        elif reg in self.regs:
            self._write_stored(reg, value, mask, now)
        elif reg == IR:
            self.ir &= ~(value & IR_MASK)
        elif reg == TSCV:
            self.ts_origin, self.ts_offset, self.ts_wraps = now, 0, 0
        elif reg in (RXF0A, RXF1A):
            if mask & 0xFF:
                self.rx[0 if reg == RXF0A else 1].acknowledge(value & 0x7)
        elif reg == TXEFA:
            if mask & 0xFF:
                self.tef.acknowledge(value & 0x3)
        elif reg == TXBAR:
            self._add_requests(value & 0x7, now)
        elif reg == TXBCR:
            self._cancel_requests(value & 0x7)
        # the read-only registers (CREL, ENDN, ECR, PSR, TOCV, HPMS, RXFnS, TXFQS, TXBRP, TXBTO, TXBCF, TXEFS)
        # ignore writes, as the chip does

    def _write_stored(self, reg: int, value: int, mask: int, now: int) -> None:
        configurable = self.cccr & (INIT | CCE) == INIT | CCE
        if (reg in PROTECTED and not configurable) or (reg == TEST and not self.cccr & TEST_EN):
            self.ignored_writes += 1
            return
        writable = WRITABLE[reg] & mask
        new = (self.regs[reg] & ~writable) | (value & writable)
        if reg == TSCC and (new & 0x3) == 0b10:
            raise BoardError(f"{self.name}: TSCC.TSS = 10 (timestamp from TIM3) is not modelled; use 01 (internal "
                             "counter) or 00")
        if reg == TOCC and new & 0x1:
            raise BoardError(f"{self.name}: TOCC.ETOC = 1 (timeout counter) is not modelled")
        if reg in (NBTP, TSCC, CKDIV):
            self._rebase_timestamp(now)
        self.regs[reg] = new

    def _write_cccr(self, new: int, now: int) -> None:
        if self.on_change is not None:
            self.on_change()
        old = self.cccr
        if new & CSR:
            new |= INIT | CSA  # clock stop: no transfer is ever half done here, so it is acknowledged at once
        else:
            new &= ~CSA
        if not new & INIT:
            new &= ~CCE  # leaving INIT clears CCE
        elif not old & INIT:
            new = (new & ~CCE) | (old & CCE)  # CCE changes only while INIT is already set
        if not (old & INIT and old & CCE):
            new = (new & ~CCCR_PROTECTED) | (old & CCCR_PROTECTED)
        if new & INIT and self.in_flight is not None:
            self.in_flight = None  # the frame on the bus is abandoned; its request stays pending
        if new & CCE and not old & CCE:
            self._clear_on_configuration()
        self.cccr = new & (0xF3FF)
        if old & INIT and not new & INIT:
            self._join_bus(self.cccr, now)
        if not new & INIT:
            self._start_next(now)

    def _clear_on_configuration(self) -> None:
        """Setting CCCR.CCE resets HPMS, RXF0S, RXF1S, TXFQS, TXBRP, TXBTO, TXBCF and TXEFS (RM0440)."""
        self.hpms = 0
        self.rx = (_Ring(), _Ring())
        self.tef = _Ring()
        self.tx_fifo = _Ring()
        self.txbrp = self.txbto = self.txbcf = 0

    def _activity(self) -> int:
        if self.cccr & INIT:
            return 0b00
        return 0b11 if self.in_flight is not None else 0b01

    # ----- clocks and the timestamp counter
    def _join_bus(self, cccr: int, now: int) -> None:
        """The firmware takes the controller out of initialisation: its kernel clock from the RCC (RCC
        CCIPR.FDCANSEL; BoardError when the source is not running) and its bit timing checked against the rates
        the run's link states (BoardError naming NBTP or DBTP and both rates)."""
        rcc = self._rcc()
        if rcc is None:
            return
        hz, source = rcc.fdcan_kernel_clock(now)
        self.kernel_clock_hz = hz
        nominal_ticks, data_ticks = self._bit_ticks()
        want_nominal, want_data = self.link_bitrates
        checks = [("NBTP", self.regs[NBTP], nominal_ticks, want_nominal, "bitrate")]
        if cccr & FDOE and cccr & BRSE:
            checks.append(("DBTP", self.regs[DBTP], data_ticks, want_data, "data_bitrate"))
        for reg, value, ticks, want, option in checks:
            rate = hz / ticks
            if want is not None and abs(rate - want) > self.BITRATE_TOLERANCE * want:
                ckdiv = f", CKDIV {self.regs[CKDIV] & 0xF}" if self.regs[CKDIV] & 0xF else ""
                raise BoardError(f"{self.name} {reg} 0x{value:08x}: {rate:.6g} bit/s ({ticks} kernel clock periods "
                                 f"per bit at {source}{ckdiv}), the run's link is {want} bit/s (link option "
                                 f"{option}): the firmware would not hear the bus")

    def clock_changed(self, now: int) -> None:
        """The RCC changed a clock FDCAN's kernel clock may come from (CCIPR, the oscillators, the PLL, the
        prescalers): out of initialisation the controller follows it as the chip does — its bit times and the
        timestamp counter at the new kernel clock from now on, the bit timing checked against the run's link again
        (BoardError naming NBTP/DBTP and both rates: the firmware would no longer hear the bus), a source that stopped
        named as at the start."""
        if self.cccr & INIT:
            return
        before = self.kernel_clock_hz
        self._join_bus(self.cccr, now)
        if self.kernel_clock_hz != before:
            self.inputs_changed()  # the next timestamp wrap moves with the clock

    def _rcc(self) -> _KernelClock | None:
        """The board's RCC model, when it names FDCAN's kernel clock (a bare bus has none)."""
        try:
            rcc = self.bus.peripheral("RCC")
        except (BoardError, KeyError):
            return None
        return rcc if isinstance(rcc, _KernelClock) else None

    def _cycles(self, kernel_ticks: int) -> int:
        """CPU cycles spanned by `kernel_ticks` periods of the FDCAN kernel clock (rounded up)."""
        if self.kernel_clock_hz is None:
            return kernel_ticks
        return -(-kernel_ticks * self.bus.sysclk_hz // self.kernel_clock_hz)

    def _bit_ticks(self) -> tuple[int, int]:
        """(nominal, data) bit time in kernel clock periods: CKDIV, then (BRP+1) x (1 + TSEG1+1 + TSEG2+1)."""
        pdiv = self.regs[CKDIV] & 0xF
        div = 1 if pdiv == 0 else 2 * pdiv
        nbtp, dbtp = self.regs[NBTP], self.regs[DBTP]
        nominal = div * (((nbtp >> 16) & 0x1FF) + 1) * (3 + ((nbtp >> 8) & 0xFF) + (nbtp & 0x7F))
        data = div * (((dbtp >> 16) & 0x1F) + 1) * (3 + ((dbtp >> 8) & 0x1F) + ((dbtp >> 4) & 0xF))
        return nominal, data

    def _frame_cycles(self, element: ram.Element) -> int:
        """CPU cycles a frame holds the bus at the configured bit rates (dynamic stuff bits left out)."""
        nominal_bits, data_bits = ram.frame_bits(element)
        nominal, data = self._bit_ticks()
        return self._cycles(nominal_bits * nominal + data_bits * data)

    def _unit_cycles(self) -> int | None:
        """CPU cycles per timestamp count (TCP+1 nominal bit times), None when the counter stands (TSS 00/11)."""
        tscc = self.regs[TSCC]
        if tscc & 0x3 != 0b01:
            return None
        return max(1, self._cycles(self._bit_ticks()[0] * (((tscc >> 16) & 0xF) + 1)))

    def _timestamp_units(self, now: int) -> int:
        unit = self._unit_cycles()
        if unit is None:
            return self.ts_offset
        return self.ts_offset + max(0, now - self.ts_origin) // unit

    def _timestamp(self, now: int) -> int:
        return self._timestamp_units(now) & 0xFFFF

    def _rebase_timestamp(self, now: int) -> None:
        units = self._timestamp_units(now)
        self.ts_origin, self.ts_offset, self.ts_wraps = now, units & 0xFFFF, 0

    def _next_wrap(self) -> int | None:
        unit = self._unit_cycles()
        if unit is None:
            return None
        return self.ts_origin + (((self.ts_wraps + 1) << 16) - self.ts_offset) * unit

    # ----- receiving
    def _element_of(self, frame: can.Message) -> ram.Element:
        limit = 0x1FFF_FFFF if frame.is_extended_id else 0x7FF
        if not 0 <= frame.arbitration_id <= limit:
            kind = "extended (29-bit)" if frame.is_extended_id else "standard (11-bit)"
            raise BoardError(f"{self.name}: received frame id 0x{frame.arbitration_id:X} is not a {kind} id")
        data = bytes(frame.data or b"")
        remote = bool(frame.is_remote_frame) and not frame.is_fd
        try:
            dlc = min(frame.dlc, 15) if remote else ram.dlc_of(len(data), bool(frame.is_fd))
        except ValueError as exc:
            raise BoardError(f"{self.name}: received frame 0x{frame.arbitration_id:X}: {exc}") from None
        fd = bool(frame.is_fd)
        return ram.Element(frame.arbitration_id, bool(frame.is_extended_id), remote, fd,
                           fd and bool(frame.bitrate_switch), fd and bool(frame.error_state_indicator), dlc,
                           b"" if remote else data)

    def _drop(self, reason: str) -> None:
        self.rx_dropped[reason] = self.rx_dropped.get(reason, 0) + 1

    def _filter(self, element: ram.Element) -> flt.Decision:
        rxgfc = self.regs[RXGFC]
        early = flt.global_decision(rxgfc, element.extended, element.remote)
        if early is not None:
            return early
        base = self.ram_base
        if element.extended:
            count = min((rxgfc >> 24) & 0xF, ram.EXT_FILTERS)
            raw = self.bus.read_memory(base + ram.FLESA, 8 * count)
            words = [int.from_bytes(raw[i:i + 4], "little") for i in range(0, len(raw), 4)]
            found = flt.match_extended(list(zip(words[0::2], words[1::2], strict=True)), element.can_id,
                                       self.regs[XIDAM])
        else:
            count = min((rxgfc >> 16) & 0x1F, ram.STD_FILTERS)
            raw = self.bus.read_memory(base + ram.FLSSA, 4 * count)
            found = flt.match_standard([int.from_bytes(raw[i:i + 4], "little") for i in range(0, len(raw), 4)],
                                       element.can_id)
        return found if found is not None else flt.non_matching(rxgfc, element.extended)

    def _receive(self, element: ram.Element, now: int) -> None:
        decision = self._filter(element)
        self.psr &= ~(0x707 if element.brs else 0x7)  # LEC (and DLEC after a data phase) 0: no error
        if element.fd:
            self.psr |= (1 << 13) | ((1 << 12) if element.brs else 0) | ((1 << 11) if element.esi else 0)
        stored: int | None = None
        lost = False
        if decision.fifo is not None:
            fifo = self.rx[decision.fifo]
            overwrite = bool(self.regs[RXGFC] & (1 << (9 - decision.fifo)))
            new, full, lost_flag = (RF0N, RF0F, RF0L) if decision.fifo == 0 else (RF1N, RF1F, RF1L)
            if fifo.fill == ram.RX_FIFO_ELEMENTS and not overwrite:
                self.ir |= lost_flag
                lost = True
            else:
                if fifo.fill == ram.RX_FIFO_ELEMENTS:
                    fifo.get = (fifo.get + 1) % 3
                    fifo.fill -= 1
                stored = fifo.push()
                start = ram.RF0SA if decision.fifo == 0 else ram.RF1SA
                self.bus.write_memory(self.ram_base + start + stored * ram.ELEMENT_BYTES,
                                      ram.encode_rx(element, self._timestamp(now - self._frame_cycles(element)),
                                                    decision.filter_index))
                self.ir |= new | (full if fifo.fill == ram.RX_FIFO_ELEMENTS else 0)
        if decision.priority:
            msi = 0b01 if lost else (0b00 if stored is None else 0b10 + (decision.fifo or 0))
            self.hpms = ((int(element.extended) << 15) | (((decision.filter_index or 0) & 0x1F) << 8) | (msi << 6)
                         | (stored or 0))
            self.ir |= HPM

    def _fifo_status(self, n: int) -> int:
        return self._ring_status(self.rx[n], bool(self.ir & (RF0L if n == 0 else RF1L)))

    @staticmethod
    def _ring_status(ring: _Ring, lost: bool) -> int:
        """RXFnS / TXEFS: lost 25, full 24, put index 17:16, get index 9:8, fill level 3:0."""
        return ((int(lost) << 25) | (int(ring.fill == 3) << 24) | (ring.put << 16) | (ring.get << 8) | ring.fill)

    # ----- transmitting
    def _queue_mode(self) -> bool:
        return bool(self.regs[TXBC] & (1 << 24))

    def _txfqs(self) -> int:
        if self._queue_mode():
            free = [i for i in range(ram.TX_BUFFERS) if not self.txbrp & (1 << i)]
            return (int(not free) << 21) | ((free[0] if free else 0) << 16)
        ring = self.tx_fifo
        return ((int(ring.fill == 3) << 21) | (ring.put << 16) | (ring.get << 8) | (ram.TX_BUFFERS - ring.fill))

    def _add_requests(self, bits: int, now: int) -> None:
        bits &= ~self.txbrp  # an add request for a pending buffer is ignored
        if not bits:
            return
        if not self._queue_mode():
            ring = self.tx_fifo
            run = [(ring.put + k) % 3 for k in range(3 - ring.fill)]
            count = 0
            while count < len(run) and bits & (1 << run[count]):
                count += 1
            if bits != sum(1 << i for i in run[:count]):
                raise BoardError(f"{self.name}: TXBAR = 0x{bits:X} adds buffers out of FIFO order (TX FIFO mode, "
                                 f"put index TXFQS.TFQPI = {ring.put}, free level {3 - ring.fill})")
            for _ in range(count):
                ring.push()
        self.txbrp |= bits
        self.txbto &= ~bits
        self.txbcf &= ~bits
        self._start_next(now)

    def _cancel_pending(self) -> int:
        flight = self.in_flight
        return (1 << flight.buffer) if flight is not None and flight.cancel else 0

    def _cancel_requests(self, bits: int) -> None:
        for index in range(ram.TX_BUFFERS):
            bit = 1 << index
            if not bits & bit & self.txbrp:
                continue
            if self.in_flight is not None and self.in_flight.buffer == index:
                self.in_flight.cancel = True  # the frame on the bus still completes
                continue
            self.txbrp &= ~bit
            self.txbcf |= bit
            if self.regs[TXBCIE] & bit:
                self.ir |= TCF
        self._release_fifo()

    def _release_fifo(self) -> None:
        """Move the TX FIFO get index past buffers no longer pending (sent or cancelled)."""
        if self._queue_mode():
            return
        ring = self.tx_fifo
        while ring.fill and not self.txbrp & (1 << ring.get):
            ring.get = (ring.get + 1) % 3
            ring.fill -= 1

    def _can_send(self) -> bool:
        internal_loopback = bool(self.cccr & TEST_EN and self.regs[TEST] & TEST_LBCK)
        return not self.cccr & (INIT | ASM) and (not self.cccr & MON or internal_loopback)

    def _next_buffer(self) -> int | None:
        pending = [i for i in range(ram.TX_BUFFERS) if self.txbrp & (1 << i)]
        if not pending:
            return None
        if not self._queue_mode():
            ring = self.tx_fifo
            order = [(ring.get + k) % 3 for k in range(3)]
            return next(i for i in order if i in pending)
        elements = {i: self._tx_element(i)[0] for i in pending}
        return min(pending, key=lambda i: (_arbitration_key(elements[i]), i))

    def _tx_element(self, index: int) -> tuple[ram.Element, ram.TxHeader]:
        raw = self.bus.read_memory(self.ram_base + ram.TFQSA + index * ram.ELEMENT_BYTES, ram.ELEMENT_BYTES)
        return ram.decode_tx(raw, bool(self.cccr & FDOE), bool(self.cccr & BRSE))

    def _start_next(self, now: int) -> None:
        if self.in_flight is not None or not self._can_send():
            return
        index = self._next_buffer()
        if index is None:
            return
        element, header = self._tx_element(index)
        self.in_flight = _InFlight(index, element, header, now, now + self._frame_cycles(element))

    def _complete(self, end: int) -> None:
        flight = self.in_flight
        assert flight is not None
        self.in_flight = None
        bit = 1 << flight.buffer
        self.txbrp &= ~bit
        self.txbto |= bit
        if self.regs[TXBTIE] & bit:
            self.ir |= TC
        if flight.cancel:
            self.txbcf |= bit
            if self.regs[TXBCIE] & bit:
                self.ir |= TCF
        if flight.header.event:
            self._store_event(flight, end)
        self.psr &= ~0x7  # LEC 0: transferred without error
        element = flight.element
        loopback = bool(self.cccr & TEST_EN and self.regs[TEST] & TEST_LBCK)
        if not (loopback and self.cccr & MON):
            self.transmitted.append(can.Message(
                timestamp=end / self.bus.sysclk_hz, arbitration_id=element.can_id, is_extended_id=element.extended,
                is_remote_frame=element.remote, is_fd=element.fd, bitrate_switch=element.brs,
                error_state_indicator=element.esi, dlc=len(element.data) if not element.remote else element.dlc,
                data=element.data, channel=self.name))
            if self.on_change is not None:
                self.on_change()
        if loopback:
            self._receive(element, end)
        if not self._queue_mode():
            was_filled = self.tx_fifo.fill
            self._release_fifo()
            if was_filled and not self.tx_fifo.fill:
                self.ir |= TFE

    def _store_event(self, flight: _InFlight, end: int) -> None:
        ring = self.tef
        if ring.fill == ram.TX_EVENT_ELEMENTS:
            self.ir |= TEFL
            return
        slot = ring.push()
        self.bus.write_memory(self.ram_base + ram.TEFSA + 8 * slot,
                              ram.encode_tx_event(flight.element, flight.header, self._timestamp(flight.start),
                                                  flight.cancel))
        self.ir |= TEFN | (TEFF if ring.fill == ram.TX_EVENT_ELEMENTS else 0)

    # ----- interrupt lines
    def _update_lines(self) -> None:
        flagged = self.ir & self.regs[IE]
        if not flagged and not (self.line_flags[0] or self.line_flags[1]):
            return
        line1 = ILS_LINE1[self.regs[ILS]]
        ile = self.regs[ILE]
        for line, routed in enumerate((flagged & ~line1, flagged & line1)):
            if not ile & (1 << line):
                routed = 0
            irq = self.irq_lines[line]
            if routed & ~self.line_flags[line]:
                self.bus.set_pending(irq)  # the line rose, or a new event joined it while it was high
            elif not routed and self.line_flags[line]:
                self.bus.clear_pending(irq)
            self.line_flags[line] = routed

    @property
    def line_state(self) -> tuple[bool, bool]:
        """Whether IT0 and IT1 are asserted."""
        return bool(self.line_flags[0]), bool(self.line_flags[1])


def _arbitration_key(element: ram.Element) -> tuple[int, int, int, int, int]:
    """Bus priority of a frame (smaller wins): the 11 base id bits, then RTR/SRR, IDE, the 18 extension bits and
    the extended RTR, as arbitration compares them."""
    if element.extended:
        return element.can_id >> 18, 1, 1, element.can_id & 0x3FFFF, int(element.remote)
    return element.can_id, int(element.remote), 0, 0, 0


__all__ = ["Fdcan"]
