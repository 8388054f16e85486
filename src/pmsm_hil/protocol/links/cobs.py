"""COBS (consistent overhead byte stuffing) with 0x00 as frame delimiter, and a resynchronising
deframer for the serial link: frame = COBS(header + payload + CRC-16/CCITT) + 0x00."""

from __future__ import annotations

import binascii
from collections.abc import Callable

from pmsm_hil.protocol.errors import ProtocolError
from pmsm_hil.protocol.links.stats import LinkStats
from pmsm_hil.protocol.links.wire import HEADER, HEADER_SIZE, MAX_PAYLOAD

CRC_INIT = 0xFFFF
CRC_SIZE = 2
MAX_RAW = HEADER_SIZE + MAX_PAYLOAD + CRC_SIZE
MAX_ENCODED = MAX_RAW + MAX_RAW // 254 + 1


class CobsError(ProtocolError, ValueError):
    """Malformed COBS block."""


def cobs_encode(data: bytes) -> bytes:
    """COBS-encode `data` (the result has no 0x00 byte; the delimiter is not appended)."""
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
    """Inverse of cobs_encode; raises CobsError on a zero byte or a block running past the end."""
    out = bytearray()
    i = 0
    n = len(enc)
    while i < n:
        code = enc[i]
        if code == 0:
            raise CobsError(f"zero byte at offset {i}")
        end = i + code
        if end > n:
            raise CobsError(f"block at offset {i} runs past the end")
        block = enc[i + 1 : end]
        if 0 in block:
            raise CobsError(f"zero byte inside block at offset {i}")
        out += block
        i = end
        if code != 0xFF and i < n:
            out.append(0)
    return bytes(out)


def encode_packet(header_and_payload: bytes) -> bytes:
    """Serial packet: COBS(header + payload + CRC-16 big-endian) + 0x00."""
    crc = binascii.crc_hqx(header_and_payload, CRC_INIT)
    return cobs_encode(header_and_payload + crc.to_bytes(2, "big")) + b"\x00"


class Deframer:
    """Splits a byte stream at 0x00, checks COBS, CRC and header; calls `on_frame(header_and_payload)`.

    Garbage is counted (framing_errors / crc_errors in `stats`) and dropped; the deframer resumes at
    the next delimiter, so no input ever raises."""

    __slots__ = ("_buf", "_discarding", "_max_encoded", "_on_frame", "_stats", "_trailer")

    def __init__(self, stats: LinkStats, on_frame: Callable[[bytes], None], trailer: int = 0) -> None:
        self._stats = stats
        self._on_frame = on_frame
        self._buf = bytearray()
        self._discarding = False
        self._trailer = trailer  # bytes after the payload (the authentication trailer)
        self._max_encoded = MAX_ENCODED + trailer

    def feed(self, chunk: bytes) -> None:
        """Consume received bytes."""
        buf = self._buf
        buf += chunk
        start = 0
        while True:
            end = buf.find(0, start)
            if end < 0:
                break
            if self._discarding:
                self._discarding = False
            elif end > start:
                self._packet(bytes(buf[start:end]))
            start = end + 1
        if start:
            del buf[:start]
        if len(buf) > self._max_encoded:
            self._stats.framing_errors += 1
            buf.clear()
            self._discarding = True

    @property
    def pending(self) -> tuple[bytes, bool]:
        """(bytes after the last delimiter, discarding until the next one): where a native loop reading the
        stream for a run continues from (`resume` hands its state back)."""
        return bytes(self._buf), self._discarding

    def resume(self, pending: bytes, discarding: bool) -> None:
        """Continue from a packet half received (`pending`) or a run being discarded."""
        self._buf[:] = pending
        self._discarding = discarding

    def _packet(self, enc: bytes) -> None:
        stats = self._stats
        if len(enc) > self._max_encoded:
            stats.framing_errors += 1
            return
        try:
            raw = cobs_decode(enc)
        except CobsError:
            stats.framing_errors += 1
            return
        if len(raw) < HEADER_SIZE + self._trailer + CRC_SIZE:
            stats.framing_errors += 1
            return
        body = raw[:-CRC_SIZE]
        if binascii.crc_hqx(body, CRC_INIT) != int.from_bytes(raw[-CRC_SIZE:], "big"):
            stats.crc_errors += 1
            return
        length = HEADER.unpack_from(body)[3]
        if self._trailer and length == len(body) - HEADER_SIZE:
            stats.auth_failed += 1  # a frame without the authentication trailer
            return
        if length != len(body) - HEADER_SIZE - self._trailer or length > MAX_PAYLOAD:
            stats.framing_errors += 1
            return
        self._on_frame(body)
