"""Frame header shared by the UDP and serial framings (little-endian).

offset 0  u32  arbitration id (bits 0..28)
offset 4  u8   flags: bit0 FD, bit1 BRS, bit2 ESI, bit3 extended id, bit4 remote
offset 5  u8   link sequence number (per sender, wraps at 256)
offset 6  u8   payload length (0..64)
offset 7  ...  payload
"""

from __future__ import annotations

import struct

HEADER = struct.Struct("<IBBB")
HEADER_SIZE = HEADER.size
MAX_PAYLOAD = 64
FLAG_FD = 0x01
FLAG_BRS = 0x02
FLAG_ESI = 0x04
FLAG_EXTENDED = 0x08
FLAG_REMOTE = 0x10
ID_MASK = 0x1FFFFFFF
FD_LENGTHS = frozenset((*range(9), 12, 16, 20, 24, 32, 48, 64))


def pack_frame(arbitration_id: int, data: bytes, flags: int, seq: int) -> bytes:
    """Header + payload; the caller checks the payload length."""
    return HEADER.pack(arbitration_id & ID_MASK, flags, seq & 0xFF, len(data)) + data


def valid_payload_length(length: int, is_fd: bool) -> bool:
    """True if `length` is a valid classic (≤ 8) or CAN FD payload length."""
    return length in FD_LENGTHS if is_fd else 0 <= length <= 8
