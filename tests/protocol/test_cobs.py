"""COBS framing and the serial deframer: round trips, resynchronisation, CRC errors, fuzzing."""

from __future__ import annotations

import binascii

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pmsm_hil.protocol.links.cobs import CobsError, Deframer, cobs_decode, cobs_encode, encode_packet
from pmsm_hil.protocol.links.stats import LinkStats
from pmsm_hil.protocol.links.wire import pack_frame


@given(st.binary(max_size=600))
def test_cobs_round_trip(data: bytes) -> None:
    enc = cobs_encode(data)
    assert 0 not in enc
    assert len(enc) <= len(data) + len(data) // 254 + 1
    assert cobs_decode(enc) == data


def test_cobs_known_vectors() -> None:
    assert cobs_encode(b"") == b"\x01"
    assert cobs_encode(b"\x00") == b"\x01\x01"
    assert cobs_encode(b"\x11\x22\x00\x33") == b"\x03\x11\x22\x02\x33"
    with pytest.raises(CobsError):
        cobs_decode(b"\x05\x11")


def collect() -> tuple[LinkStats, list[bytes], Deframer]:
    stats = LinkStats()
    got: list[bytes] = []
    return stats, got, Deframer(stats, got.append)


def test_deframer_resyncs_after_garbage_and_counts() -> None:
    stats, got, d = collect()
    body = pack_frame(0x108, bytes(range(16)), 1, 0)
    pkt = encode_packet(body)
    crc = binascii.crc_hqx(body, 0xFFFF) ^ 0x0001
    corrupt = cobs_encode(body + crc.to_bytes(2, "big")) + b"\x00"  # valid COBS, wrong CRC
    d.feed(b"\x37\x99garbage" + b"\x00" + bytes(corrupt) + pkt[:5])
    d.feed(pkt[5:] + pkt)
    assert got == [body, body]
    assert stats.crc_errors == 1
    assert stats.framing_errors == 1  # the garbage before the first delimiter


def test_deframer_overlong_run_discarded() -> None:
    stats, got, d = collect()
    d.feed(b"\x55" * 500)
    d.feed(b"\x00" + encode_packet(pack_frame(1, b"x", 0, 0)))
    assert stats.framing_errors == 1
    assert got == [pack_frame(1, b"x", 0, 0)]


def test_deframer_length_mismatch_is_framing_error() -> None:
    stats, got, d = collect()
    body = pack_frame(1, b"abc", 0, 0)[:-1]  # header says 3 bytes, 2 present
    crc = binascii.crc_hqx(body, 0xFFFF).to_bytes(2, "big")
    d.feed(cobs_encode(body + crc) + b"\x00")
    assert got == [] and stats.framing_errors == 1


@given(st.lists(st.binary(max_size=120), max_size=20))
@settings(max_examples=300, deadline=None)
def test_fuzz_deframer_never_raises(chunks: list[bytes]) -> None:
    _stats, got, d = collect()
    for c in chunks:
        d.feed(c)
    assert all(len(b) >= 7 for b in got)


@given(
    frames=st.lists(st.tuples(st.integers(0, 0x7FF), st.binary(max_size=64)), max_size=10),
    noise=st.binary(max_size=40),
    split=st.integers(1, 50),
)
@settings(max_examples=200, deadline=None)
def test_frames_survive_noise_prefix_and_arbitrary_chunking(
    frames: list[tuple[int, bytes]], noise: bytes, split: int
) -> None:
    _stats, got, d = collect()
    bodies = [pack_frame(i, data, 1, k) for k, (i, data) in enumerate(frames)]
    stream = noise + b"\x00" + b"".join(encode_packet(b) for b in bodies)
    for k in range(0, len(stream), split):
        d.feed(stream[k : k + split])
    assert got == bodies
