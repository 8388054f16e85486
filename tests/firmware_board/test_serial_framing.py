"""The C serial framing of the board layer (firmware_stub/target/hil_serial.c) against the reference of
docs/protocol.md (tests/protocol/wire_oracle.py): identical packets both ways, resynchronisation after garbage, CRC
errors counted."""

from __future__ import annotations

import ctypes
import random
from pathlib import Path

import pytest

from pmsm_hil.sim_target.fw_build import FIRMWARE_DIR
from tests.host_c import STRICT, shared_library
from tests.protocol.test_cobs import _received
from tests.protocol.wire_oracle import FLAG_BRS, FLAG_FD, encode_packet, pack_frame


class _Frame(ctypes.Structure):
    _fields_ = [("id", ctypes.c_uint32), ("len", ctypes.c_uint8), ("fd", ctypes.c_uint8),
                ("data", ctypes.c_uint8 * 64)]


class _Serial(ctypes.Structure):
    _fields_ = [("buf", ctypes.c_uint8 * 74), ("n", ctypes.c_uint16), ("discarding", ctypes.c_uint8),
                ("tx_seq", ctypes.c_uint8), ("framing_errors", ctypes.c_uint32), ("crc_errors", ctypes.c_uint32),
                ("ignored", ctypes.c_uint32)]


@pytest.fixture(scope="module")
def lib(tmp_path_factory: pytest.TempPathFactory) -> ctypes.CDLL:
    target = FIRMWARE_DIR / "target"
    lib = shared_library(tmp_path_factory.mktemp("serial") / "libhil_serial.so",
                         [*STRICT, "-O2", "-I", str(target), "-I", str(FIRMWARE_DIR / "generated"),
                          str(target / "hil_serial.c")])
    lib.hil_serial_encode.restype = ctypes.c_size_t
    lib.hil_serial_feed.argtypes = [ctypes.POINTER(_Serial), ctypes.c_uint8, ctypes.POINTER(_Frame)]
    return lib


def _frames(n: int) -> list[tuple[int, bytes, bool]]:
    rng = random.Random(7)
    out = []
    for _ in range(n):
        fd = rng.random() < 0.5
        length = rng.choice((0, 3, 8, 12, 16, 20, 24, 64)) if fd else rng.randint(0, 8)
        data = bytes(rng.choice((0, 1, 0xFF, rng.randint(0, 255))) for _ in range(length))
        out.append((rng.randint(0, 0x7FF), data, fd))
    return out


def test_c_encode_equals_python(lib: ctypes.CDLL) -> None:
    ser = _Serial()
    lib.hil_serial_init(ctypes.byref(ser))
    for seq, (ident, data, fd) in enumerate(_frames(300)):
        f = _Frame(ident, len(data), 1 if fd else 0)
        f.data[:len(data)] = list(data)
        buf = (ctypes.c_uint8 * 100)()
        n = lib.hil_serial_encode(ctypes.byref(ser), ctypes.byref(f), buf)
        expected = encode_packet(pack_frame(ident, data, (FLAG_FD | FLAG_BRS) if fd else 0, seq))
        assert bytes(buf[:n]) == expected


def test_c_decode_of_python_packets_with_garbage(lib: ctypes.CDLL) -> None:
    ser = _Serial()
    lib.hil_serial_init(ctypes.byref(ser))
    frames = _frames(200)
    stream = b"\x05garbage\x00"
    for seq, (ident, data, fd) in enumerate(frames):
        packet = encode_packet(pack_frame(ident, data, FLAG_FD if fd else 0, seq))
        if seq == 50:  # a corrupted packet: CRC error, dropped, the next one decodes
            packet = packet[:3] + bytes([packet[3] ^ 0x10 or 1]) + packet[4:]
        stream += packet
    got = []
    out = _Frame()
    for b in stream:
        if lib.hil_serial_feed(ctypes.byref(ser), b, ctypes.byref(out)):
            got.append((out.id, bytes(out.data[:out.len]), bool(out.fd)))
    assert got == [f for i, f in enumerate(frames) if i != 50]
    assert ser.crc_errors + ser.framing_errors == 2  # the corrupted packet and the leading garbage


def test_the_host_serial_bus_accepts_the_boards_packets(lib: ctypes.CDLL) -> None:
    ser = _Serial()
    lib.hil_serial_init(ctypes.byref(ser))
    packets = []
    frames = _frames(100)
    for ident, data, fd in frames:
        f = _Frame(ident, len(data), 1 if fd else 0)
        f.data[:len(data)] = list(data)
        buf = (ctypes.c_uint8 * 100)()
        packets.append(bytes(buf[:lib.hil_serial_encode(ctypes.byref(ser), ctypes.byref(f), buf)]))
    got, stats = _received(packets)
    assert got == frames and stats.crc_errors == stats.framing_errors == 0


def test_struct_mirror_matches_header() -> None:
    header = (Path(FIRMWARE_DIR) / "target" / "hil_serial.h").read_text()
    assert "HIL_SERIAL_MAX_ENCODED" in header  # _Serial.buf: 7 + 64 + 2 = 73 raw, +73/254 + 1 = 74 encoded
