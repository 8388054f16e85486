"""Sizes of the UDP and serial framings (docs/protocol.md), for the link budget; the framing itself is C
(src/pmsm_hil/hil/runner/c/links: loop_udp.c, loop_serial.c; the python-can buses of wire_bus.py). The frame header
both share (little-endian):

offset 0  u32  arbitration id (bits 0..28)
offset 4  u8   flags: bit0 FD, bit1 BRS, bit2 ESI, bit3 extended id, bit4 remote
offset 5  u8   link sequence number (per sender, wraps at 256)
offset 6  u8   payload length (0..64)
offset 7  ...  payload
"""

from __future__ import annotations

HEADER_SIZE = 7
#: CRC-16/CCITT-FALSE (init 0xFFFF, big endian) after header + payload (+ the authentication trailer)
CRC_SIZE = 2
