"""FDCAN1 of the virtual STM32G474 against RM0440: configuration protection, acceptance filtering, RX FIFOs, TX
FIFO/queue, the TX event FIFO, interrupt lines and CAN FD lengths, driven register by register as firmware does, on a
fake board that holds the message RAM in a bytearray."""

from __future__ import annotations

import can
import cantools
import pytest

from pmsm_hil.protocol.paths import REPO_ROOT
from pmsm_hil.sim_target.stm32g4.peripherals import fdcan_ram as ram
from pmsm_hil.sim_target.stm32g4.peripherals.base import REGISTRY, BoardError
from pmsm_hil.sim_target.stm32g4.peripherals.fdcan import (
    CCCR,
    CKDIV,
    DBTP,
    IE,
    ILE,
    ILS,
    IR,
    NBTP,
    PSR,
    RXF0A,
    RXF0S,
    RXF1S,
    RXGFC,
    TEST,
    TSCC,
    TSCV,
    TXBAR,
    TXBC,
    TXBCF,
    TXBCIE,
    TXBCR,
    TXBRP,
    TXBTIE,
    TXBTO,
    TXEFA,
    TXEFS,
    TXFQS,
    XIDAM,
    Fdcan,
)
from tests.board.fake_bus import FakeBus

RAM = ram.SRAMCAN_BASE
IRQ_IT0, IRQ_IT1 = 21, 22
INIT, CCE, MON, TEST_EN, FDOE, BRSE = 1, 2, 1 << 5, 1 << 7, 1 << 8, 1 << 9
RF0N, RF0F, RF0L, RF1N, HPM, TC, TCF, TFE, TEFN, TEFF, TEFL = (
    1 << 0, 1 << 1, 1 << 2, 1 << 3, 1 << 6, 1 << 7, 1 << 8, 1 << 9, 1 << 10, 1 << 11, 1 << 12)
#: the reset bit timing: NBRP 0, NTSEG1 10, NTSEG2 3 -> 16 kernel clock periods a bit (kernel clock = SYSCLK)
BIT = 16


class CanBus(FakeBus):
    """The fake board with SRAMCAN as its RAM, read and written by offset into it."""

    def __init__(self) -> None:
        super().__init__(ram_base=RAM, ram_size=3 * ram.INSTANCE_SIZE)

    def ram_word(self, offset: int) -> int:
        return int.from_bytes(self.sram[offset:offset + 4], "little")

    def put_word(self, offset: int, value: int) -> None:
        self.sram[offset:offset + 4] = value.to_bytes(4, "little")


@pytest.fixture()
def bus() -> CanBus:
    return CanBus()


@pytest.fixture()
def fdcan(bus: CanBus) -> Fdcan:
    return Fdcan(bus)


def configure(dev: Fdcan, regs: dict[int, int] | None = None, cccr: int = 0) -> None:
    """The firmware's set-up: INIT, CCE, protected registers (offset -> value), then leave INIT with `cccr`."""
    dev.write(CCCR, 4, INIT, 0)
    dev.write(CCCR, 4, INIT | CCE, 0)
    for offset, value in (regs or {}).items():
        dev.write(offset, 4, value, 0)
    dev.write(CCCR, 4, cccr, 0)


def std_filter(sft: int, sfec: int, id1: int, id2: int) -> int:
    return (sft << 30) | (sfec << 27) | (id1 << 16) | id2


def put_tx(bus: CanBus, index: int, can_id: int, data: bytes, *, extended: bool = False, fd: bool = False,
           brs: bool = False, efc: bool = False, marker: int = 0) -> None:
    """Write TX buffer `index` as firmware does (T0, T1, payload words)."""
    base = ram.TFQSA + index * ram.ELEMENT_BYTES
    bus.put_word(base, (1 << 30 | can_id) if extended else can_id << 18)
    dlc = ram.dlc_of(len(data), fd)
    bus.put_word(base + 4, (marker << 24) | (int(efc) << 23) | (int(fd) << 21) | (int(brs) << 20) | (dlc << 16))
    padded = data + bytes(-len(data) % 4)
    bus.sram[base + 8:base + 8 + len(padded)] = padded


def rx_element(bus: CanBus, fifo: int, index: int) -> tuple[int, int, bytes]:
    """(R0, R1, the 64 payload bytes) of RX FIFO `fifo` element `index`."""
    base = (ram.RF0SA if fifo == 0 else ram.RF1SA) + index * ram.ELEMENT_BYTES
    return bus.ram_word(base), bus.ram_word(base + 4), bytes(bus.sram[base + 8:base + ram.ELEMENT_BYTES])


def msg(can_id: int, data: bytes = b"", **kw: bool) -> can.Message:
    return can.Message(arbitration_id=can_id, data=data, is_extended_id=kw.pop("extended", False), **kw)


# ----- registry, reset values, configuration protection

def test_registered_at_rm0440_addresses(bus: CanBus) -> None:
    dev = REGISTRY["FDCAN1"](bus)
    assert isinstance(dev, Fdcan) and dev.base == 0x4000_6400 and dev.irq_lines == (21, 22)
    assert (ram.FLESA, ram.RF0SA, ram.RF1SA, ram.TEFSA, ram.TFQSA) == (0x70, 0xB0, 0x188, 0x260, 0x278)


def test_reset_values(fdcan: Fdcan) -> None:
    assert fdcan.read(CCCR, 4, 0) == INIT
    assert fdcan.read(NBTP, 4, 0) == 0x0600_0A03 and fdcan.read(DBTP, 4, 0) == 0x0000_0A33
    assert fdcan.read(XIDAM, 4, 0) == 0x1FFF_FFFF
    assert fdcan.read(0x000, 4, 0) == 0x3214_1218 and fdcan.read(0x004, 4, 0) == 0x8765_4321
    assert fdcan.read(PSR, 4, 0) == 0x707  # LEC/DLEC 7, ACT 00 (synchronising) in INIT
    assert fdcan.read(TXFQS, 4, 0) == 3  # FIFO mode, 3 free
    assert fdcan.read(0x040, 4, 0) == 0  # ECR: no errors


def test_protected_registers_change_only_in_init_with_cce(fdcan: Fdcan) -> None:
    fdcan.write(NBTP, 4, 0x1234_0501, 0)  # INIT set, CCE clear: ignored
    assert fdcan.read(NBTP, 4, 0) == 0x0600_0A03 and fdcan.ignored_writes == 1
    fdcan.write(CCCR, 4, INIT | CCE | FDOE, 0)  # FDOE is protected: not in the write that sets CCE
    assert fdcan.read(CCCR, 4, 0) == INIT | CCE
    fdcan.write(CCCR, 4, INIT | CCE | FDOE, 0)
    assert fdcan.read(CCCR, 4, 0) == INIT | CCE | FDOE
    fdcan.write(NBTP, 4, 0x1234_0501, 0)
    fdcan.write(RXGFC, 4, 0x3F, 0)
    assert fdcan.read(NBTP, 4, 0) == 0x1234_0501 and fdcan.read(RXGFC, 4, 0) == 0x3F
    fdcan.write(CCCR, 4, FDOE, 0)  # leave INIT: CCE is cleared with it, at once
    assert fdcan.read(CCCR, 4, 0) == FDOE
    fdcan.write(NBTP, 4, 0, 0)
    fdcan.write(CCCR, 4, BRSE, 0)  # FDOE/BRSE are protected too
    assert fdcan.read(NBTP, 4, 0) == 0x1234_0501 and fdcan.read(CCCR, 4, 0) == FDOE
    fdcan.write(CCCR, 4, INIT | CCE, 0)  # CCE cannot be set in the same write that sets INIT
    assert fdcan.read(CCCR, 4, 0) == INIT | FDOE
    fdcan.write(TEST, 4, 0x10, 0)  # TEST needs CCCR.TEST
    assert fdcan.read(TEST, 4, 0) & 0x10 == 0


def test_clock_stop_request_is_acknowledged(fdcan: Fdcan) -> None:
    configure(fdcan)
    fdcan.write(CCCR, 4, 1 << 4, 0)  # CSR
    assert fdcan.read(CCCR, 4, 0) & (INIT | 1 << 3) == INIT | 1 << 3  # INIT and CSA
    fdcan.write(CCCR, 4, INIT, 0)
    assert fdcan.read(CCCR, 4, 0) & (1 << 3) == 0


def test_unmodelled_offsets_and_modes_name_the_register(fdcan: Fdcan) -> None:
    with pytest.raises(BoardError, match=r"FDCAN1: read of reserved offset 0x030 \(address 0x40006430\)"):
        fdcan.read(0x030, 4, 0)
    with pytest.raises(BoardError, match="crosses a register"):
        fdcan.read(0x052, 4, 0)
    fdcan.write(CCCR, 4, INIT | CCE, 0)
    with pytest.raises(BoardError, match=r"TSCC\.TSS = 10"):
        fdcan.write(TSCC, 4, 0b10, 0)


def test_byte_access_and_write_one_to_clear(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan)
    fdcan.deliver(msg(0x10, b"\x01"), 100)
    assert fdcan.read(IR, 1, 100) == RF0N
    fdcan.write(IR + 1, 1, 0xFF, 100)  # other byte: RF0N stays
    assert fdcan.read(IR, 4, 100) == RF0N
    fdcan.write(IR, 1, RF0N, 100)
    assert fdcan.read(IR, 4, 100) == 0


# ----- acceptance filtering

def test_standard_filters_range_dual_classic_first_match_wins(fdcan: Fdcan, bus: CanBus) -> None:
    filters = [
        std_filter(0b01, 0b011, 0x300, 0x301),  # 0: dual, reject 0x300/0x301
        std_filter(0b00, 0b001, 0x200, 0x2FF),  # 1: range -> FIFO 0
        std_filter(0b10, 0b010, 0x700, 0x7F0),  # 2: classic 0x70x -> FIFO 1
        std_filter(0b00, 0b010, 0x000, 0x7FF),  # 3: everything else -> FIFO 1, but outside LSS
    ]
    for i, word in enumerate(filters):
        bus.put_word(ram.FLSSA + 4 * i, word)
    configure(fdcan, {RXGFC: (3 << 16) | (0b10 << 4)})  # LSS 3, ANFS reject
    for can_id in (0x300, 0x301, 0x200, 0x2FF, 0x70F, 0x710, 0x100):
        fdcan.deliver(msg(can_id, b"\xAA"), 10)
    assert fdcan.read(RXF0S, 4, 10) & 0xF == 2 and fdcan.read(RXF1S, 4, 10) & 0xF == 1
    r0, r1, _ = rx_element(bus, 0, 0)
    assert (r0 >> 18) & 0x7FF == 0x200 and (r1 >> 24) & 0x7F == 1 and not r1 & (1 << 31)
    r0, r1, _ = rx_element(bus, 1, 0)
    assert (r0 >> 18) & 0x7FF == 0x70F and (r1 >> 24) & 0x7F == 2


def test_non_matching_and_remote_frames_follow_the_global_filter(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan, {RXGFC: (0b01 << 4) | (0b10 << 2) | 0b10})  # ANFS FIFO 1, ANFE reject, RRFS
    fdcan.deliver(msg(0x123, b"\x01"), 5)
    fdcan.deliver(msg(0x1234567, b"\x01", extended=True), 6)
    fdcan.deliver(can.Message(arbitration_id=0x124, is_remote_frame=True, dlc=2, is_extended_id=False), 7)
    assert fdcan.read(RXF1S, 4, 7) & 0xF == 1 and fdcan.read(RXF0S, 4, 7) & 0xF == 0
    _, r1, _ = rx_element(bus, 1, 0)
    assert r1 & (1 << 31)  # ANMF: accepted without a matching filter


def test_extended_filters_with_and_without_the_id_mask(fdcan: Fdcan, bus: CanBus) -> None:
    pairs = [
        ((0b011 << 29) | 0x0000_0005, (0b01 << 30) | 0x0000_0006),  # 0: dual 5/6 -> reject
        ((0b001 << 29) | 0x0010_0000, (0b10 << 30) | 0x1FF0_0000),  # 1: classic: 0x001xxxxx -> FIFO 0
        ((0b010 << 29) | 0x1000_0000, (0b11 << 30) | 0x1000_00FF),  # 2: range, no mask -> FIFO 1
    ]
    for i, (f0, f1) in enumerate(pairs):
        bus.put_word(ram.FLESA + 8 * i, f0)
        bus.put_word(ram.FLESA + 8 * i + 4, f1)
    # LSE 3, ANFE reject; XIDAM clears bit 28, so 0x1000_0010 is seen as 0x10 by the masked filters
    configure(fdcan, {RXGFC: (3 << 24) | (0b10 << 2), XIDAM: 0x0FFF_FFFF})
    for can_id in (0x5, 0x0012_3456, 0x1000_0010, 0x1000_0100):
        fdcan.deliver(msg(can_id, b"\x00", extended=True), 1)
    assert fdcan.read(RXF0S, 4, 1) & 0xF == 1 and fdcan.read(RXF1S, 4, 1) & 0xF == 1
    r0, _, _ = rx_element(bus, 0, 0)
    assert r0 == (1 << 30) | 0x0012_3456
    r0, r1, _ = rx_element(bus, 1, 0)
    assert r0 == (1 << 30) | 0x1000_0010 and (r1 >> 24) & 0x7F == 2


def test_high_priority_match_sets_hpm_and_hpms(fdcan: Fdcan, bus: CanBus) -> None:
    bus.put_word(ram.FLSSA, std_filter(0b01, 0b010, 0x700, 0x701))
    bus.put_word(ram.FLSSA + 4, std_filter(0b01, 0b110, 0x080, 0x080))  # set priority and store in FIFO 1
    configure(fdcan, {RXGFC: 2 << 16})
    fdcan.deliver(msg(0x700), 1)
    fdcan.deliver(msg(0x080), 2)
    assert fdcan.read(IR, 4, 2) & HPM
    assert fdcan.read(0x088, 4, 2) == (1 << 8) | (0b11 << 6) | 1  # FIDX 1, MSI FIFO 1, BIDX 1


# ----- RX FIFOs

def test_rx_fifo_indices_wrap_and_acknowledge(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan)
    for n in range(3):
        fdcan.deliver(msg(0x10 + n, bytes([n])), 10 + n)
    status = fdcan.read(RXF0S, 4, 20)
    assert status == (1 << 24) | (0 << 16) | (0 << 8) | 3  # full, put 0, get 0, 3 elements
    assert fdcan.read(IR, 4, 20) & (RF0N | RF0F) == RF0N | RF0F
    fdcan.write(RXF0A, 4, 1, 20)  # the firmware read elements 0 and 1
    assert fdcan.read(RXF0S, 4, 20) == (0 << 16) | (2 << 8) | 1
    fdcan.deliver(msg(0x20, b"\x20"), 30)
    fdcan.deliver(msg(0x21, b"\x21"), 31)
    assert fdcan.read(RXF0S, 4, 31) == (1 << 24) | (2 << 16) | (2 << 8) | 3
    assert [rx_element(bus, 0, i)[2][0] for i in range(3)] == [0x20, 0x21, 2]
    fdcan.write(RXF0A, 4, 1, 40)  # elements 2, 0, 1 read: the index wraps
    assert fdcan.read(RXF0S, 4, 40) == (2 << 16) | (2 << 8) | 0


def test_full_fifo_loses_the_new_frame_in_blocking_mode(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan)
    for n in range(4):
        fdcan.deliver(msg(0x10, bytes([n])), n)
    status = fdcan.read(RXF0S, 4, 5)
    assert status & (1 << 25) and status & 0xF == 3 and fdcan.read(IR, 4, 5) & RF0L
    assert [rx_element(bus, 0, i)[2][0] for i in range(3)] == [0, 1, 2]  # the fourth frame was lost
    fdcan.write(IR, 4, RF0L, 5)
    assert not fdcan.read(RXF0S, 4, 5) & (1 << 25)  # RXF0S.RF0L mirrors IR.RF0L


def test_full_fifo_overwrites_the_oldest_in_overwrite_mode(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan, {RXGFC: 1 << 9})  # F0OM
    for n in range(4):
        fdcan.deliver(msg(0x10, bytes([n])), n)
    assert fdcan.read(RXF0S, 4, 5) == (1 << 24) | (1 << 16) | (1 << 8) | 3
    assert [rx_element(bus, 0, i)[2][0] for i in range(3)] == [3, 1, 2]
    assert not fdcan.read(IR, 4, 5) & RF0L


def test_frames_are_not_received_in_init_nor_error_frames(fdcan: Fdcan) -> None:
    fdcan.deliver(msg(0x10, b"\x00"), 1)
    configure(fdcan)
    fdcan.deliver(can.Message(is_error_frame=True), 2)
    assert fdcan.read(RXF0S, 4, 2) == 0
    assert fdcan.rx_dropped == {"not synchronised (CCCR.INIT set)": 1, "error frame": 1}


# ----- CAN FD

@pytest.mark.parametrize("dlc", range(16))
def test_fd_lengths_and_header_bits(fdcan: Fdcan, bus: CanBus, dlc: int) -> None:
    configure(fdcan, cccr=FDOE | BRSE)
    data = bytes(range(ram.FD_LENGTHS[dlc]))
    fdcan.deliver(can.Message(arbitration_id=0x108, data=data, is_fd=True, bitrate_switch=True,
                              error_state_indicator=True, is_extended_id=False), 1)
    r0, r1, payload = rx_element(bus, 0, 0)
    assert r0 == (1 << 31) | (0x108 << 18)  # ESI
    assert (r1 >> 16) & 0xF == dlc and r1 & (1 << 21) and r1 & (1 << 20)  # DLC, FDF, BRS
    assert payload[:len(data)] == data


def test_invalid_lengths_and_fd_without_fdoe(fdcan: Fdcan) -> None:
    configure(fdcan)
    with pytest.raises(BoardError, match=r"0x108: payload length 10 bytes is not a valid CAN FD \(0-8"):
        fdcan.deliver(can.Message(arbitration_id=0x108, data=bytes(10), is_fd=True, is_extended_id=False), 1)
    fdcan.deliver(can.Message(arbitration_id=0x108, data=bytes(12), is_fd=True, is_extended_id=False), 1)
    assert fdcan.read(RXF0S, 4, 1) == 0 and fdcan.rx_dropped == {"CAN FD frame with CCCR.FDOE clear": 1}


def test_fd_frame_sent_with_64_bytes_and_bit_rate_switch(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan, {DBTP: (1 << 8) | (0 << 4)}, cccr=FDOE | BRSE)  # data phase: 1 + 2 + 1 = 4 periods a bit
    data = bytes(range(64))
    put_tx(bus, 0, 0x119, data, fd=True, brs=True)
    fdcan.write(TXBAR, 4, 1, 1000)
    nominal_bits, data_bits = ram.frame_bits(ram.Element(0x119, False, False, True, True, False, 15, data))
    end = 1000 + nominal_bits * BIT + data_bits * 4
    assert fdcan.next_event(1000) == end
    fdcan.advance(end)
    (sent,) = fdcan.take_transmitted()
    assert sent.is_fd and sent.bitrate_switch and bytes(sent.data) == data and sent.arbitration_id == 0x119
    assert sent.timestamp == pytest.approx(end / 170e6)


# ----- transmitting

def test_tx_fifo_sends_in_request_order_and_takes_bus_time(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan)
    for k, can_id in enumerate((0x300, 0x100, 0x200)):
        assert (fdcan.read(TXFQS, 4, 0) >> 16) & 0x3 == k  # put index
        put_tx(bus, k, can_id, bytes([k] * 8))
        fdcan.write(TXBAR, 4, 1 << k, 0)
    assert fdcan.read(TXFQS, 4, 0) & (1 << 21)  # full
    assert fdcan.read(TXBRP, 4, 0) == 0b111
    frame = (47 + 64) * BIT  # classic standard 8-byte frame, stuff bits left out
    assert fdcan.read(0x044, 4, frame - 1) & 0x18 == 0x18  # PSR.ACT transmitter
    assert fdcan.read(TXBRP, 4, frame - 1) == 0b111
    assert fdcan.read(TXBRP, 4, frame) == 0b110 and fdcan.read(TXBTO, 4, frame) == 0b001
    assert fdcan.read(TXFQS, 4, frame) == (1 << 8) | 1  # get index 1, one free
    fdcan.advance(3 * frame)
    sent = fdcan.take_transmitted()
    assert [m.arbitration_id for m in sent] == [0x300, 0x100, 0x200]  # FIFO: request order, not id priority
    assert [m.timestamp * 170e6 for m in sent] == pytest.approx([frame, 2 * frame, 3 * frame])
    assert fdcan.read(IR, 4, 3 * frame) & TFE and fdcan.read(TXBTO, 4, 3 * frame) == 0b111
    assert fdcan.take_transmitted() == []


def test_tx_queue_sends_the_highest_priority_id_first(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan, {TXBC: 1 << 24})
    fdcan.write(CCCR, 4, INIT, 0)  # requests wait while INIT is set
    put_tx(bus, 0, 0x300, b"\x00")
    put_tx(bus, 1, 0x100, b"\x01", extended=True)  # extended 0x100: base id 0, wins arbitration
    put_tx(bus, 2, 0x005, b"\x02")
    assert (fdcan.read(TXFQS, 4, 0) >> 16) & 3 == 0
    fdcan.write(TXBAR, 4, 0b111, 0)
    assert fdcan.read(TXFQS, 4, 0) == 1 << 21  # queue: full, free level/get index read 0
    fdcan.write(CCCR, 4, 0, 0)
    fdcan.advance(10**6)
    assert [(m.arbitration_id, m.is_extended_id) for m in fdcan.take_transmitted()] == [
        (0x100, True), (0x005, False), (0x300, False)]


def test_tx_fifo_refuses_requests_out_of_order(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan)
    with pytest.raises(BoardError, match=r"TXBAR = 0x2 adds buffers out of FIFO order .*put index TXFQS.TFQPI = 0"):
        fdcan.write(TXBAR, 4, 0b010, 0)


def test_transmission_interrupt_and_tx_event_fifo(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan, {TSCC: (0 << 16) | 0b01})  # timestamp counts bit times
    fdcan.write(TXBTIE, 4, 0b001, 0)
    fdcan.write(IE, 4, TC | TEFN, 0)
    fdcan.write(ILE, 4, 0b01, 0)
    put_tx(bus, 0, 0x701, b"\x01\x02\x03", efc=True, marker=0x5A)
    start = 100 * BIT
    fdcan.write(TXBAR, 4, 1, start)
    end = start + (47 + 24) * BIT
    fdcan.advance(end)
    assert bus.pended == [IRQ_IT0]
    assert fdcan.read(IR, 4, end) & (TC | TEFN) == TC | TEFN
    assert fdcan.read(TXEFS, 4, end) == (1 << 16) | 1
    e0, e1 = bus.ram_word(ram.TEFSA), bus.ram_word(ram.TEFSA + 4)
    assert e0 == 0x701 << 18
    assert e1 >> 24 == 0x5A and (e1 >> 22) & 3 == 0b01 and (e1 >> 16) & 0xF == 3
    assert e1 & 0xFFFF == 100  # TXTS: the timestamp at the start of the frame
    fdcan.write(TXEFA, 4, 0, end)
    assert fdcan.read(TXEFS, 4, end) == (1 << 16) | (1 << 8)
    fdcan.write(IR, 4, TC | TEFN, end)
    assert bus.cleared == [IRQ_IT0]


def test_tx_event_fifo_overflow_sets_tefl(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan, {TXBC: 1 << 24})
    for n in range(4):
        put_tx(bus, 0, 0x10 + n, b"", efc=True)
        fdcan.write(TXBAR, 4, 1, n * 10**4)
        fdcan.advance(n * 10**4 + 5000)
    status = fdcan.read(TXEFS, 4, 10**5)
    assert status & (1 << 25) and status & (1 << 24) and status & 0x7 == 3
    assert fdcan.read(IR, 4, 10**5) & (TEFF | TEFL) == TEFF | TEFL
    assert [bus.ram_word(ram.TEFSA + 8 * i) >> 18 for i in range(3)] == [0x10, 0x11, 0x12]


def test_cancellation_of_waiting_and_ongoing_transmissions(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan, {TXBC: 1 << 24})
    fdcan.write(TXBCIE, 4, 0b011, 0)
    put_tx(bus, 0, 0x10, b"\x00", efc=True)
    put_tx(bus, 1, 0x20, b"\x01")
    fdcan.write(TXBAR, 4, 0b011, 0)  # buffer 0 goes on the bus at once, buffer 1 waits
    fdcan.write(TXBCR, 4, 0b011, 10)
    assert fdcan.read(TXBCF, 4, 10) == 0b010 and fdcan.read(TXBRP, 4, 10) == 0b001
    assert fdcan.read(TXBCR, 4, 10) == 0b001 and fdcan.read(IR, 4, 10) & TCF
    fdcan.advance(10**5)
    assert [m.arbitration_id for m in fdcan.take_transmitted()] == [0x10]
    assert fdcan.read(TXBTO, 4, 10**5) == 0b001 and fdcan.read(TXBCF, 4, 10**5) == 0b011
    assert (bus.ram_word(ram.TEFSA + 4) >> 22) & 3 == 0b10  # sent in spite of cancellation
    fdcan.write(TXBAR, 4, 0b001, 10**5)  # a new request clears TXBTO/TXBCF of that buffer
    assert fdcan.read(TXBTO, 4, 10**5) == 0 and fdcan.read(TXBCF, 4, 10**5) == 0b010


def test_setting_cce_resets_fifo_and_request_state(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan)
    fdcan.deliver(msg(0x1, b"\x01"), 1)
    put_tx(bus, 0, 0x2, b"")
    fdcan.write(TXBAR, 4, 1, 1)
    fdcan.write(CCCR, 4, INIT, 2)  # the frame on the bus is abandoned, its request stays
    assert fdcan.read(TXBRP, 4, 2) == 1 and fdcan.next_event(2) is None
    fdcan.write(CCCR, 4, INIT | CCE, 2)
    assert fdcan.read(RXF0S, 4, 2) == 0 and fdcan.read(TXBRP, 4, 2) == 0 and fdcan.read(TXFQS, 4, 2) == 3


def test_internal_loopback_receives_its_own_frames(fdcan: Fdcan, bus: CanBus) -> None:
    fdcan.write(CCCR, 4, INIT | CCE, 0)
    fdcan.write(CCCR, 4, INIT | CCE | TEST_EN | MON, 0)
    fdcan.write(TEST, 4, 0x10, 0)  # LBCK
    fdcan.write(CCCR, 4, TEST_EN | MON, 0)
    put_tx(bus, 0, 0x42, b"\x42")
    fdcan.write(TXBAR, 4, 1, 0)
    fdcan.advance(10**4)
    assert fdcan.take_transmitted() == []  # internal loopback: nothing on the bus
    r0, _, payload = rx_element(bus, 0, 0)
    assert r0 == 0x42 << 18 and payload[0] == 0x42


def test_bit_timing_and_clock_divider_set_the_frame_time(fdcan: Fdcan, bus: CanBus) -> None:
    # 1 Mbit/s from 170 MHz is not whole; take NBRP 9 (x10), 1 + 12 + 4 = 17 periods, CKDIV /2: 340 cycles a bit
    configure(fdcan, {NBTP: (9 << 16) | (11 << 8) | 3, CKDIV: 1})
    put_tx(bus, 0, 0x1, b"")
    fdcan.write(TXBAR, 4, 1, 0)
    assert fdcan.next_event(0) == 47 * 340


def test_frame_cycles_for_the_run_side(fdcan: Fdcan) -> None:
    configure(fdcan, {DBTP: 1 << 8}, cccr=FDOE | BRSE)  # data phase 4 periods a bit
    assert fdcan.frame_cycles(msg(0x200, bytes(7))) == (47 + 56) * BIT
    assert fdcan.frame_cycles(msg(0x1234, bytes(8), extended=True)) == (67 + 64) * BIT
    fd = can.Message(arbitration_id=0x108, data=bytes(16), is_fd=True, bitrate_switch=True, is_extended_id=False)
    assert fdcan.frame_cycles(fd) == (17 + 12) * BIT + (1 + 4 + 128 + 4 + 17 + 1 + 5 + 1) * 4


# ----- interrupt lines

def test_ils_routes_groups_to_the_second_line_and_ile_gates(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan, {RXGFC: 0b01 << 4})  # non-matching standard frames -> FIFO 1
    fdcan.write(IE, 4, RF0N | RF1N, 0)
    fdcan.write(ILS, 4, 0b010, 0)  # RXFIFO1 group -> IT1
    fdcan.deliver(msg(0x1, b""), 1)
    assert bus.pended == []  # ILE off
    fdcan.write(ILE, 4, 0b10, 1)
    assert bus.pended == [IRQ_IT1] and fdcan.line_active(1) and not fdcan.line_active(0)
    fdcan.deliver(msg(0x2, b""), 2)
    assert bus.pended == [IRQ_IT1]  # RF1N already holds the line up: no new event
    fdcan.write(ILS, 4, 0, 3)  # the group moves to IT0, whose EINT0 is off
    assert bus.cleared == [IRQ_IT1] and bus.pended == [IRQ_IT1] and not fdcan.line_active(1)
    fdcan.write(ILE, 4, 0b11, 3)
    assert fdcan.line_active(0) and bus.pended == [IRQ_IT1, IRQ_IT0]
    fdcan.write(IR, 4, RF1N, 4)
    assert not fdcan.line_active(0) and bus.cleared == [IRQ_IT1, IRQ_IT0]


def test_a_new_event_on_a_high_line_pends_again(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan)
    fdcan.write(IE, 4, RF0N | RF0F, 0)
    fdcan.write(ILE, 4, 0b01, 0)
    fdcan.deliver(msg(0x1), 1)
    fdcan.deliver(msg(0x2), 2)
    fdcan.deliver(msg(0x3), 3)  # the FIFO fills: RF0F joins RF0N on IT0
    assert bus.pended == [IRQ_IT0, IRQ_IT0]


def test_timestamp_counter_and_wrap_interrupt(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan, {TSCC: (1 << 16) | 0b01})  # a count every 2 bit times
    assert fdcan.read(TSCV, 4, 2 * BIT * 100) == 100
    wrap = fdcan.next_event(0)
    assert wrap == 2 * BIT * 65536
    fdcan.advance(wrap)
    assert fdcan.read(IR, 4, wrap) & (1 << 13)  # TSW
    fdcan.write(TSCV, 4, 0, wrap)
    assert fdcan.read(TSCV, 4, wrap + 2 * BIT) == 1
    fdcan.deliver(msg(0x10, bytes(8)), wrap + 2 * BIT * 500)  # 111 bits long: it started 55.5 counts earlier
    _, r1, _ = rx_element(bus, 0, 0)
    assert r1 & 0xFFFF == 500 - 56  # RXTS: the timestamp at the start of the frame


# ----- the project's DBC through the controller

def test_dbc_setpoint_in_and_heartbeat_out(fdcan: Fdcan, bus: CanBus) -> None:
    """A firmware that takes Setpoint and ConfigParam into FIFO 0 (one dual filter, everything else rejected) and
    answers with HeartbeatTarget: the bytes are the DBC's, both ways."""
    db = cantools.database.load_file(str(REPO_ROOT / "src" / "pmsm_hil" / "protocol" / "hil.dbc"))
    setpoint = db.get_message_by_name("Setpoint")
    heartbeat = db.get_message_by_name("HeartbeatTarget")
    config_param = db.get_message_by_name("ConfigParam")
    bus.put_word(ram.FLSSA, std_filter(0b01, 0b001, setpoint.frame_id, config_param.frame_id))
    configure(fdcan, {RXGFC: (1 << 16) | (0b10 << 4) | (0b10 << 2) | 0b11}, cccr=FDOE | BRSE)
    payload = setpoint.encode({"enable": 1, "mode": 0, "reference": 157.0, "controller_id": 6})
    fdcan.deliver(can.Message(arbitration_id=setpoint.frame_id, data=payload, is_extended_id=False), 100)
    fdcan.deliver(can.Message(arbitration_id=0x100, data=bytes(8), is_extended_id=False), 200)  # MeasA: rejected
    assert fdcan.read(RXF0S, 4, 200) & 0xF == 1
    r0, r1, data = rx_element(bus, 0, 0)
    length = ram.payload_length((r1 >> 16) & 0xF, bool(r1 & (1 << 21)))
    decoded = setpoint.decode(data[:length])
    assert (r0 >> 18) & 0x7FF == 0x200 and decoded["reference"] == pytest.approx(157.0)
    put_tx(bus, 0, heartbeat.frame_id, heartbeat.encode({"node": 1, "state": 2, "counter": 7}))
    fdcan.write(TXBAR, 4, 1, 300)
    fdcan.advance(10**5)
    (sent,) = fdcan.take_transmitted()
    assert sent.arbitration_id == 0x701 and not sent.is_fd
    assert heartbeat.decode(bytes(sent.data), decode_choices=False) == {"node": 1, "state": 2, "counter": 7}


def test_fd_request_without_fdoe_goes_classic(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan)
    put_tx(bus, 0, 0x108, bytes(range(16)), fd=True, brs=True)
    fdcan.write(TXBAR, 4, 1, 0)
    fdcan.advance(10**5)
    (sent,) = fdcan.take_transmitted()
    assert not sent.is_fd and not sent.bitrate_switch and bytes(sent.data) == bytes(range(8))


def test_external_loopback_sends_and_receives(fdcan: Fdcan, bus: CanBus) -> None:
    fdcan.write(CCCR, 4, INIT | CCE, 0)
    fdcan.write(CCCR, 4, INIT | CCE | TEST_EN, 0)
    fdcan.write(TEST, 4, 0x10, 0)
    fdcan.write(CCCR, 4, TEST_EN, 0)
    put_tx(bus, 0, 0x55, b"\x55")
    fdcan.write(TXBAR, 4, 1, 0)
    fdcan.advance(10**4)
    assert [m.arbitration_id for m in fdcan.take_transmitted()] == [0x55]
    assert fdcan.read(RXF0S, 4, 10**4) & 0xF == 1


def test_high_priority_frame_lost_in_a_full_fifo(fdcan: Fdcan, bus: CanBus) -> None:
    bus.put_word(ram.FLSSA, std_filter(0b01, 0b101, 0x001, 0x001))  # priority, FIFO 0
    configure(fdcan, {RXGFC: 1 << 16})
    for n in range(4):
        fdcan.deliver(msg(0x001, bytes([n])), n)
    assert (fdcan.read(0x088, 4, 4) >> 6) & 0x3 == 0b01  # MSI: FIFO message lost
    assert fdcan.read(IR, 4, 4) & (HPM | RF0L) == HPM | RF0L


def test_reserved_write_names_the_offset(fdcan: Fdcan) -> None:
    with pytest.raises(BoardError, match=r"FDCAN1: write of reserved offset 0x104 \(address 0x40006504\)"):
        fdcan.write(0x104, 4, 1, 0)


def test_remote_request_goes_classic_even_with_fdf(fdcan: Fdcan, bus: CanBus) -> None:
    configure(fdcan, cccr=FDOE | BRSE)
    put_tx(bus, 0, 0x321, b"", fd=True, brs=True)
    bus.put_word(ram.TFQSA, bus.ram_word(ram.TFQSA) | (1 << 29))  # RTR
    bus.put_word(ram.TFQSA + 4, bus.ram_word(ram.TFQSA + 4) | (4 << 16))  # DLC 4: four bytes requested
    fdcan.write(TXBAR, 4, 1, 0)
    fdcan.advance(10**5)
    (sent,) = fdcan.take_transmitted()
    assert sent.is_remote_frame and not sent.is_fd and sent.dlc == 4 and bytes(sent.data) == b""


# ----- a HAL-style driver, register by register

def _rmw(dev: Fdcan, offset: int, clear: int, set_bits: int, now: int) -> None:
    """MODIFY_REG / SET_BIT / CLEAR_BIT as the HAL and LL drivers do them: a 32-bit read, then a 32-bit write."""
    dev.write(offset, 4, (dev.read(offset, 4, now) & ~clear) | set_bits, now)


def test_hal_style_bring_up_receive_and_send(fdcan: Fdcan, bus: CanBus) -> None:
    """The order of operations of STM32CubeG4's HAL_FDCAN_Init, ConfigFilter, ConfigGlobalFilter,
    ActivateNotification, Start, GetRxMessage and AddMessageToTxFifoQ: every poll ends at once and the frames go
    through."""
    now = 0
    _rmw(fdcan, CCCR, 1 << 4, 0, now)  # leave clock stop
    assert not fdcan.read(CCCR, 4, now) & (1 << 3)  # CSA
    _rmw(fdcan, CCCR, 0, INIT, now)
    assert fdcan.read(CCCR, 4, now) & INIT
    _rmw(fdcan, CCCR, 0, CCE, now)
    _rmw(fdcan, CCCR, 1 << 6, 0, now)  # automatic retransmission on (DAR clear)
    _rmw(fdcan, CCCR, FDOE | BRSE, FDOE | BRSE, now)  # FrameFormat FD with BRS
    _rmw(fdcan, CCCR, TEST_EN | MON | (1 << 2), 0, now)  # normal mode
    _rmw(fdcan, TEST, 0x10, 0, now)  # ignored: CCCR.TEST clear, as the chip ignores it
    # 170 MHz kernel clock: nominal 1 Mbit/s = 170 periods (NBRP 9 -> 10 x (1 + 13 + 3)), data 5 Mbit/s = 34
    fdcan.write(NBTP, 4, (2 << 25) | (9 << 16) | (12 << 8) | 2, now)
    fdcan.write(DBTP, 4, (1 << 16) | (12 << 8) | (2 << 4) | 2, now)
    _rmw(fdcan, TXBC, 1 << 24, 0, now)  # TX FIFO mode
    fdcan.write(CKDIV, 4, 0, now)
    _rmw(fdcan, RXGFC, 0x0F1F_0000, (1 << 16) | (0 << 24), now)  # one standard filter
    bus.sram[0:ram.INSTANCE_SIZE] = bytes(ram.INSTANCE_SIZE)  # the driver clears its message RAM
    bus.put_word(ram.FLSSA, std_filter(0b01, 0b001, 0x200, 0x210))  # Setpoint, ConfigParam -> FIFO 0
    _rmw(fdcan, RXGFC, 0x3F, (0b10 << 4) | (0b10 << 2) | 0b11, now)  # reject the rest
    _rmw(fdcan, ILS, 0x7F, 0, now)
    _rmw(fdcan, IE, 0, RF0N | TC, now)
    fdcan.write(TXBTIE, 4, 0b111, now)
    _rmw(fdcan, ILE, 0, 0b01, now)
    _rmw(fdcan, CCCR, INIT, 0, now)  # HAL_FDCAN_Start
    assert fdcan.read(CCCR, 4, now) & (INIT | CCE) == 0 and fdcan.ignored_writes == 1

    fdcan.deliver(can.Message(arbitration_id=0x210, data=b"\x07\x00\x00\x80\x3f", is_extended_id=False), 5000)
    assert bus.pended == [IRQ_IT0]
    status = fdcan.read(RXF0S, 4, 5100)  # HAL_FDCAN_GetRxMessage
    assert status & 0xF == 1
    get = (status >> 8) & 0x3
    base = ram.RF0SA + get * ram.ELEMENT_BYTES
    r1 = bus.ram_word(base + 4)
    length = ram.payload_length((r1 >> 16) & 0xF, bool(r1 & (1 << 21)))
    assert (bus.ram_word(base) >> 18) & 0x7FF == 0x210
    assert bytes(bus.sram[base + 8:base + 8 + length]) == b"\x07\x00\x00\x80\x3f"
    fdcan.write(RXF0A, 4, get, 5100)
    fdcan.write(IR, 4, RF0N, 5100)
    assert bus.cleared == [IRQ_IT0] and fdcan.read(RXF0S, 4, 5100) & 0xF == 0

    assert not fdcan.read(TXFQS, 4, 6000) & (1 << 21)  # HAL_FDCAN_AddMessageToTxFifoQ
    put = (fdcan.read(TXFQS, 4, 6000) >> 16) & 0x3
    put_tx(bus, put, 0x211, b"\x07\x00\x00\x80\x3f\x00", fd=True, brs=True)
    fdcan.write(TXBAR, 4, 1 << put, 6000)
    end = fdcan.next_event(6000)
    assert end == 6000 + (17 + 12) * 170 + (1 + 4 + 48 + 4 + 17 + 1 + 5 + 1) * 34  # 1 Mbit/s arbitration, 5 Mbit/s data
    fdcan.advance(end)
    (sent,) = fdcan.take_transmitted()
    assert sent.arbitration_id == 0x211 and sent.is_fd and sent.bitrate_switch and len(sent.data) == 6
    assert bus.pended == [IRQ_IT0, IRQ_IT0] and fdcan.read(IR, 4, end) & TC
