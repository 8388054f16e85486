"""FrameDecoder reassembly and counters; fuzzing with random frames never raises."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from pmsm_hil.protocol.codec import FrameCodec, FrameDecoder
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.messages import Command, Measurement


def meas(seq: int) -> Measurement:
    return Measurement(seq, 1.0, -0.5, -0.5, 1.0, 10.0, 48.0, 0)


def cmd(seq: int) -> Command:
    return Command(seq, (4, 6, 7), (1000, 2000, 3000), 1, 8, 500, 0)


def test_duplicate_frames_are_dropped_and_counted() -> None:
    codec = FrameCodec("can")
    dec = codec.decoder()
    a, b = codec.encode(meas(5))
    assert dec.feed(a) is None
    assert dec.feed(a) is None  # same part twice
    got = dec.feed(b)
    assert isinstance(got, Measurement) and got.seq == 5
    assert dec.stats.duplicate == 1 and dec.stats.messages == 1
    assert dec.feed(b) is None  # after delivery: same seq again
    assert dec.stats.duplicate == 2


def test_out_of_order_parts_still_assemble() -> None:
    codec = FrameCodec("can")
    dec = codec.decoder()
    frames = codec.encode(cmd(9))
    assert dec.feed(frames[2]) is None
    assert dec.feed(frames[0]) is None
    msg = dec.feed(frames[1])
    assert msg == cmd(9)
    assert dec.stats.out_of_order == 1


def test_mixed_seq_drops_the_incomplete_message() -> None:
    codec = FrameCodec("can")
    dec = codec.decoder()
    old = codec.encode(cmd(10))
    new = codec.encode(cmd(11))
    dec.feed(old[0])
    dec.feed(old[1])
    assert dec.feed(new[0]) is None
    assert dec.stats.mixed_seq == 1
    assert dec.feed(old[2]) is None  # part of the abandoned, older message
    assert dec.stats.stale == 1
    dec.feed(new[1])
    assert dec.feed(new[2]) == cmd(11)


def test_meas_b_low_byte_must_match() -> None:
    codec = FrameCodec("can")
    dec = codec.decoder()
    a1, _ = codec.encode(meas(0x0101))
    _, b2 = codec.encode(meas(0x0102))
    dec.feed(a1)
    assert dec.feed(b2) is None  # newer seq: the held part A is abandoned
    assert dec.stats.mixed_seq == 1
    a2, _ = codec.encode(meas(0x0102))
    got = dec.feed(a2)
    assert isinstance(got, Measurement) and got.seq == 0x0102


def test_stale_message_after_newer_delivered() -> None:
    codec = FrameCodec("canfd")
    dec = codec.decoder()
    assert dec.feed(codec.encode(meas(100))[0]) is not None
    assert dec.feed(codec.encode(meas(99))[0]) is None
    assert dec.stats.stale == 1
    assert dec.feed(codec.encode(meas(101))[0]) is not None
    # a jump by more than the stale window is a sender restart / jump: accepted
    assert dec.feed(codec.encode(meas(40000))[0]) is not None
    # wrap-around: 65535 -> 0 is a newer message; 65534 afterwards is stale
    assert dec.feed(codec.encode(meas(65535))[0]) is not None
    assert dec.feed(codec.encode(meas(0))[0]) is not None
    assert dec.feed(codec.encode(meas(65534))[0]) is None
    assert dec.stats.stale == 2 and dec.stats.messages == 5


def test_bad_frames_counted() -> None:
    dec = FrameDecoder()
    assert dec.feed(Frame(0x7AB, b"\x00", False)) is None
    assert dec.feed(Frame(0x100, bytes(7), False)) is None
    assert dec.feed(Frame(0x118, bytes(20), True)) is None  # n_states = 0
    s = dec.stats
    assert (s.frames, s.unknown_id, s.bad_length, s.bad_value, s.messages) == (3, 1, 1, 1, 0)
    assert s.as_dict()["bad_value"] == 1


ids = st.sampled_from(
    [
        0x010,
        0x011,
        0x100,
        0x101,
        0x108,
        0x110,
        0x111,
        0x112,
        0x118,
        0x200,
        0x210,
        0x211,
        0x700,
        0x701,
        0x7FF,
        0x000,
    ]
)


@given(frames=st.lists(st.builds(Frame, ids, st.binary(max_size=64), st.booleans()), max_size=60))
@settings(max_examples=400, deadline=None)
def test_fuzz_decoder_never_raises(frames: list[Frame]) -> None:
    dec = FrameDecoder()
    for fr in frames:
        dec.feed(fr)
    s = dec.stats
    assert s.frames == len(frames)
    assert s.messages <= s.frames
    assert s.unknown_id + s.bad_length + s.bad_value <= s.frames


@given(data=st.lists(st.binary(min_size=8, max_size=8), min_size=1, max_size=30))
@settings(max_examples=200, deadline=None)
def test_fuzz_right_length_random_payloads(data: list[bytes]) -> None:
    dec = FrameDecoder()
    for i, d in enumerate(data):
        msg = dec.feed(Frame((0x100, 0x101, 0x110, 0x111)[i % 4], d, False))
        if isinstance(msg, Command):
            assert 1 <= len(msg.states) <= 3 and len(msg.durations_ns) == len(msg.states)
