"""The serial link's COBS framing and deframer (the hilserial bus, loop_serial.c): round trips, resynchronisation,
CRC errors, fuzzing — packets written by the reference of docs/protocol.md (wire_oracle.py), received by the C bus."""

from __future__ import annotations

import fcntl
import os
import socket
import struct
import termios
import time

from hypothesis import given, settings
from hypothesis import strategies as st

from pmsm_hil.protocol.links.stats import LinkStats
from pmsm_hil.protocol.links.wire_bus import HilSerialBus
from tests.protocol.wire_oracle import (
    FLAG_BRS,
    FLAG_FD,
    CobsError,
    cobs_decode,
    cobs_encode,
    crc16,
    encode_packet,
    pack_frame,
)


def _unread(sock: socket.socket) -> int:
    """Bytes written to `sock` that its peer has not read yet (SIOCOUTQ of a Unix stream socket)."""
    return int(struct.unpack("i", fcntl.ioctl(sock.fileno(), termios.TIOCOUTQ, b"\0" * 4))[0])


def _received(chunks: list[bytes]) -> tuple[list[tuple[int, bytes, bool]], LinkStats]:
    """The frames (id, payload, FD) and counters of a hilserial bus reading `chunks` from its port, each written
    once the bus has read the one before and has no frame left to give: a poll that finds nothing after every
    byte written had been read (the socket's out-queue empty before it) ends the chunk, so no wait is a guess."""
    a, b = socket.socketpair()
    with a:
        bus = HilSerialBus(f"fd:{b.detach()}")
        got = []
        try:
            for chunk in chunks:
                a.sendall(chunk)
                deadline = time.monotonic() + 30.0  # a bus that stopped reading: the comparison then fails
                while time.monotonic() < deadline:
                    unread = _unread(a)
                    fr = bus.poll_frame()
                    if fr is not None:
                        got.append((fr.arbitration_id, fr.data, fr.is_fd))
                    elif unread == 0:
                        break
                    else:
                        time.sleep(0.0005)
            return got, LinkStats(**bus.link_stats.as_dict())
        finally:
            bus.shutdown()


def test_the_reference_cobs_round_trips() -> None:
    """The test's own encoder (what the other tests write with) against known vectors."""
    assert cobs_encode(b"") == b"\x01"
    assert cobs_encode(b"\x00") == b"\x01\x01"
    assert cobs_encode(b"\x11\x22\x00\x33") == b"\x03\x11\x22\x02\x33"
    assert cobs_decode(cobs_encode(bytes(600))) == bytes(600)
    try:
        cobs_decode(b"\x05\x11")
    except CobsError:
        pass
    else:
        raise AssertionError("a block past the end decoded")


def test_the_bus_sends_the_documented_packet() -> None:
    a, b = socket.socketpair()
    with a:
        bus = HilSerialBus(f"fd:{b.detach()}")
        try:
            bus.send_frame(0x108, bytes(range(16)), True)
            bus.send_frame(0x109, b"\x00\x01", False)
            a.settimeout(1.0)
            data = b""
            while data.count(b"\x00") < 2:
                data += a.recv(4096)
        finally:
            bus.shutdown()
    assert data == (encode_packet(pack_frame(0x108, bytes(range(16)), FLAG_FD | FLAG_BRS, 0))
                    + encode_packet(pack_frame(0x109, b"\x00\x01", 0, 1)))


def test_deframer_resyncs_after_garbage_and_counts() -> None:
    body = pack_frame(0x108, bytes(range(16)), 1, 0)
    pkt = encode_packet(body)
    again = encode_packet(pack_frame(0x108, bytes(range(16)), 1, 1))
    crc = int.from_bytes(crc16(body), "big") ^ 0x0001
    corrupt = cobs_encode(body + crc.to_bytes(2, "big")) + b"\x00"  # valid COBS, wrong CRC
    got, stats = _received([b"\x37\x99garbage" + b"\x00" + corrupt + pkt[:5], pkt[5:] + again])
    assert got == [(0x108, bytes(range(16)), True)] * 2
    assert stats.crc_errors == 1
    assert stats.framing_errors == 1  # the garbage before the first delimiter


def test_deframer_overlong_run_discarded() -> None:
    got, stats = _received([b"\x55" * 500, b"\x00" + encode_packet(pack_frame(1, b"x", 0, 0))])
    assert stats.framing_errors == 1
    assert got == [(1, b"x", False)]


def test_deframer_length_mismatch_is_framing_error() -> None:
    body = pack_frame(1, b"abc", 0, 0)[:-1]  # header says 3 bytes, 2 present
    got, stats = _received([cobs_encode(body + crc16(body)) + b"\x00"])
    assert got == [] and stats.framing_errors == 1


@given(st.lists(st.binary(max_size=120), max_size=20))
@settings(max_examples=60, deadline=None)
def test_fuzz_deframer_never_raises(chunks: list[bytes]) -> None:
    got, stats = _received([b"".join(chunks)])
    assert stats.frames_rx == len(got)


@given(
    frames=st.lists(st.tuples(st.integers(0, 0x7FF), st.sampled_from([0, 1, 8, 12, 64])), max_size=10),
    noise=st.binary(max_size=40),
    split=st.integers(1, 50),
)
@settings(max_examples=40, deadline=None)
def test_frames_survive_noise_prefix_and_arbitrary_chunking(frames: list[tuple[int, int]], noise: bytes,
                                                            split: int) -> None:
    sent = [(i, os.urandom(n), True) for i, n in frames]
    stream = noise + b"\x00" + b"".join(encode_packet(pack_frame(i, data, FLAG_FD, k))
                                        for k, (i, data, _) in enumerate(sent))
    got, _ = _received([stream[k:k + split] for k in range(0, len(stream), split)])
    assert got == sent
