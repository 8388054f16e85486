"""The STM32G4 FDCAN message RAM (SRAMCAN): its fixed layout and the element formats of RM0440.

Each FDCAN instance owns 0x350 bytes of SRAMCAN (FDCAN1 at 0x4000A400), laid out by the hardware, not by
software: 28 standard filters (1 word), 8 extended filters (2 words), RX FIFO 0 and RX FIFO 1 (3 elements of 18
words), the TX event FIFO (3 elements of 2 words) and the TX buffers (3 elements of 18 words).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

SRAMCAN_BASE = 0x4000_A400
INSTANCE_SIZE = 0x350
STD_FILTERS = 28
EXT_FILTERS = 8
RX_FIFO_ELEMENTS = 3
TX_EVENT_ELEMENTS = 3
TX_BUFFERS = 3
ELEMENT_BYTES = 18 * 4

# Byte offsets of the sections from the instance's start (RM0440 "Message RAM", HAL's SRAMCAN_*SA)
FLSSA = 0x000
FLESA = FLSSA + STD_FILTERS * 4
RF0SA = FLESA + EXT_FILTERS * 8
RF1SA = RF0SA + RX_FIFO_ELEMENTS * ELEMENT_BYTES
TEFSA = RF1SA + RX_FIFO_ELEMENTS * ELEMENT_BYTES
TFQSA = TEFSA + TX_EVENT_ELEMENTS * 8
assert TFQSA + TX_BUFFERS * ELEMENT_BYTES == INSTANCE_SIZE

#: DLC code -> payload length [byte] of a CAN FD frame (classic frames: min(DLC, 8))
FD_LENGTHS = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)

# Bits of the first header word (R0 / T0 / E0)
ESI = 1 << 31
XTD = 1 << 30
RTR = 1 << 29
ID_MASK = 0x1FFF_FFFF
STD_ID_SHIFT = 18
# Bits of the second header word (R1 / T1 / E1)
ANMF = 1 << 31
FDF = 1 << 21
BRS = 1 << 20
EFC = 1 << 23
DLC_SHIFT = 16


def payload_length(dlc: int, fd: bool) -> int:
    """Bytes carried by a frame with data length code `dlc` (0..15)."""
    return FD_LENGTHS[dlc] if fd else min(dlc, 8)


def dlc_of(length: int, fd: bool) -> int:
    """The DLC code of a payload of `length` bytes; ValueError for a length the frame format cannot carry."""
    if fd and length in FD_LENGTHS:
        return FD_LENGTHS.index(length)
    if not fd and 0 <= length <= 8:
        return length
    kind = "CAN FD (0-8, 12, 16, 20, 24, 32, 48, 64)" if fd else "classic CAN (0-8)"
    raise ValueError(f"payload length {length} bytes is not a valid {kind} length")


@dataclass(frozen=True)
class Element:
    """One frame as an RX/TX buffer element holds it (the header fields of RM0440, payload bytes)."""

    can_id: int
    extended: bool
    remote: bool
    fd: bool
    brs: bool
    esi: bool
    dlc: int
    data: bytes

    def id_word(self) -> int:
        """The first header word (R0/T0/E0): ESI, XTD, RTR and the identifier (standard ids in bits 28:18)."""
        ident = self.can_id if self.extended else self.can_id << STD_ID_SHIFT
        return ((ESI if self.esi else 0) | (XTD if self.extended else 0) | (RTR if self.remote else 0)
                | (ident & ID_MASK))


def decode_id_word(word: int) -> tuple[int, bool, bool, bool]:
    """(identifier, extended, remote, esi) of a first header word."""
    extended = bool(word & XTD)
    ident = word & ID_MASK if extended else (word >> STD_ID_SHIFT) & 0x7FF
    return ident, extended, bool(word & RTR), bool(word & ESI)


def encode_rx(element: Element, timestamp: int, filter_index: int | None) -> bytes:
    """An RX FIFO element: R0, R1 (ANMF when no filter matched, FIDX, FDF, BRS, DLC, RXTS) and the payload words."""
    r1 = ((ANMF if filter_index is None else (filter_index & 0x7F) << 24) | (FDF if element.fd else 0)
          | (BRS if element.brs else 0) | (element.dlc << DLC_SHIFT) | (timestamp & 0xFFFF))
    padded = element.data + bytes(-len(element.data) % 4)
    return element.id_word().to_bytes(4, "little") + r1.to_bytes(4, "little") + padded


class TxHeader(NamedTuple):
    """The part of a TX buffer element beside the frame: the event FIFO request and the message marker."""

    event: bool
    marker: int


def decode_tx(raw: bytes, fd_enabled: bool, brs_enabled: bool) -> tuple[Element, TxHeader]:
    """A TX buffer element (T0, T1, payload) as the controller sends it: FDF counts only with CCCR.FDOE, BRS only
    with CCCR.BRSE, RTR sends a classic remote frame even with FDF set, a classic frame carries at most 8 bytes."""
    t0 = int.from_bytes(raw[0:4], "little")
    t1 = int.from_bytes(raw[4:8], "little")
    ident, extended, remote, esi = decode_id_word(t0)
    fd = bool(t1 & FDF) and fd_enabled and not remote
    brs = fd and bool(t1 & BRS) and brs_enabled
    dlc = (t1 >> DLC_SHIFT) & 0xF
    length = 0 if remote else payload_length(dlc, fd)
    element = Element(ident, extended, remote, fd, brs, esi and fd, dlc, bytes(raw[8:8 + length]))
    return element, TxHeader(bool(t1 & EFC), (t1 >> 24) & 0xFF)


def encode_tx_event(element: Element, header: TxHeader, timestamp: int, cancelled: bool) -> bytes:
    """A TX event FIFO element: E0 (as T0) and E1 (MM, ET 01 sent / 10 sent in spite of cancellation, EDL, BRS,
    DLC, TXTS)."""
    e1 = ((header.marker << 24) | ((0b10 if cancelled else 0b01) << 22) | (FDF if element.fd else 0)
          | (BRS if element.brs else 0) | (element.dlc << DLC_SHIFT) | (timestamp & 0xFFFF))
    return element.id_word().to_bytes(4, "little") + e1.to_bytes(4, "little")


def frame_bits(element: Element) -> tuple[int, int]:
    """(bits at the nominal rate, bits at the data rate) of a frame on the bus, interframe space included and
    dynamic stuff bits excluded (a lower bound of its bus time). The data phase is empty without BRS."""
    n = 0 if element.remote else len(element.data)
    if not element.fd:
        return (67 if element.extended else 47) + 8 * n, 0
    arbitration = 36 if element.extended else 17  # SOF .. BRS
    crc = 17 if n <= 16 else 21
    data = 1 + 4 + 8 * n + 4 + crc + 1 + (4 + crc) // 4 + 1  # ESI, DLC, data, stuff count, CRC, fixed stuff, delim
    tail = 12  # ACK, ACK delimiter, EOF, IFS
    if element.brs:
        return arbitration + tail, data
    return arbitration + data + tail, 0
