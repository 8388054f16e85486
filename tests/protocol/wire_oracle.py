"""A reference of the hiludp / hilserial wire formats written from docs/protocol.md, only for the tests: it crafts
and reads the bytes the C links (src/pmsm_hil/hil/runner/c/links, wire_bus.py) must send and accept — frame header,
COBS, CRC-16 and the authentication trailer. The product's wires are C only; this is the independent check."""

from __future__ import annotations

import binascii
import hmac
import struct

HEADER = struct.Struct("<IBBB")  # id, flags, link seq, payload length
HEADER_SIZE = HEADER.size
FLAG_FD, FLAG_BRS, FLAG_ESI, FLAG_EXTENDED, FLAG_REMOTE = 0x01, 0x02, 0x04, 0x08, 0x10
CRC_INIT = 0xFFFF
CRC_SIZE = 2
FRESH_SIZE, MAC_SIZE = 2, 4
TRAILER = FRESH_SIZE + MAC_SIZE
AUTH_OK, AUTH_FAILED, AUTH_REPLAYED = 1, 0, -1


class CobsError(ValueError):
    """A malformed COBS block (the reference decoder's)."""


def pack_frame(arbitration_id: int, data: bytes, flags: int, seq: int) -> bytes:
    """Header + payload."""
    return HEADER.pack(arbitration_id & 0x1FFFFFFF, flags, seq & 0xFF, len(data)) + data


def crc16(data: bytes) -> bytes:
    """CRC-16/CCITT-FALSE of `data`, big endian."""
    return binascii.crc_hqx(data, CRC_INIT).to_bytes(CRC_SIZE, "big")


def cobs_encode(data: bytes) -> bytes:
    """COBS with 0x00 as delimiter (not appended)."""
    out = bytearray()
    for seg in data.split(b"\x00"):
        while len(seg) >= 254:
            out.append(0xFF)
            out += seg[:254]
            seg = seg[254:]
        out.append(len(seg) + 1)
        out += seg
    return bytes(out)


def cobs_decode(enc: bytes) -> bytes:
    """Inverse of cobs_encode; CobsError on a zero byte or a block past the end."""
    out = bytearray()
    i, n = 0, len(enc)
    while i < n:
        code = enc[i]
        if code == 0 or i + code > n or 0 in enc[i + 1:i + code]:
            raise CobsError(f"bad block at offset {i}")
        out += enc[i + 1:i + code]
        i += code
        if code != 0xFF and i < n:
            out.append(0)
    return bytes(out)


def encode_packet(body: bytes) -> bytes:
    """A serial packet: COBS(header + payload [+ trailer] + CRC-16) + 0x00."""
    return cobs_encode(body + crc16(body)) + b"\x00"


class Sealer:
    """One end's authentication (docs/protocol.md "Authenticated frames"): a trailer of the freshness's low 16 bits
    (u16 LE) and the first 4 bytes of HMAC-SHA256(key, direction || context || freshness u64 LE || body)."""

    def __init__(self, key: bytes, role: str) -> None:
        self.key = key
        self.tx_dir, self.rx_dir = (b"T", b"H") if role == "target" else (b"H", b"T")
        self.context = b""
        self.tx_fresh = self.rx_fresh = 0

    def set_context(self, context: bytes) -> None:
        self.context = context
        self.tx_fresh = self.rx_fresh = 0

    def mac(self, direction: bytes, fresh: int, body: bytes) -> bytes:
        return hmac.digest(self.key, direction + self.context + struct.pack("<Q", fresh) + body, "sha256")[:MAC_SIZE]

    def seal(self, body: bytes) -> bytes:
        self.tx_fresh += 1
        return body + struct.pack("<H", self.tx_fresh & 0xFFFF) + self.mac(self.tx_dir, self.tx_fresh, body)

    def open(self, sealed: bytes) -> int:
        """AUTH_OK, AUTH_FAILED (the MAC) or AUTH_REPLAYED (the freshness not ahead)."""
        n = len(sealed) - TRAILER
        if n < 0:
            return AUTH_FAILED
        body, last = sealed[:n], self.rx_fresh
        low = struct.unpack_from("<H", sealed, n)[0]
        ahead = (low - last) & 0xFFFF
        fresh = last + ahead if 0 < ahead < 0x8000 else (last - ((last - low) & 0xFFFF)) % (1 << 64)
        if not hmac.compare_digest(self.mac(self.rx_dir, fresh, body), sealed[n + FRESH_SIZE:]):
            return AUTH_FAILED
        if fresh <= last:
            return AUTH_REPLAYED
        self.rx_fresh = fresh
        return AUTH_OK


#: a hiludp datagram starts with the session id (u32 LE); session 0: a control datagram (HELLO / ACK)
SESSION = struct.Struct("<I")
CONTROL = struct.Struct("<I4sBBI")  # session 0, magic, type, version, session id
MAGIC, VERSION = b"HILS", 1
HELLO, ACK = 1, 2
