"""Python codec: round trips, cross-checks against cantools, encode policy and strict decoding."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pmsm_hil.protocol import Command, ConfigAck, ConfigParam, Fault, Heartbeat, Measurement, Message, Setpoint
from pmsm_hil.protocol.codec import PROFILES, FrameCodec, decode_frame, decode_message
from pmsm_hil.protocol.errors import DecodeError, EncodeError, ProtocolError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.layout import load_database

from .strategies import any_message, commands, measurements

DB = load_database()
HALF_LSB = {
    "i_a": 0.0005,
    "i_b": 0.0005,
    "i_c": 0.0005,
    "theta_e": math.pi / 65536,
    "omega_m": 0.01,
    "vdc": 0.005,
}


def assert_close(msg: Message, back: Message) -> None:
    """Equal within half an LSB of scaled fields; float32 fields equal after float32 rounding."""
    assert type(back) is type(msg)
    for f in dataclasses.fields(msg):
        a, b = getattr(msg, f.name), getattr(back, f.name)
        if f.name in HALF_LSB:
            if f.name == "theta_e":
                d = abs(a - b) % (2 * math.pi)
                assert min(d, 2 * math.pi - d) <= HALF_LSB[f.name] + 1e-12, (f.name, a, b)
            else:
                assert abs(a - b) <= HALF_LSB[f.name] + 1e-9, (f.name, a, b)
        elif isinstance(a, float):
            assert b == pytest.approx(a, rel=1e-6, abs=0.0), (f.name, a, b)
        else:
            assert a == b, (f.name, a, b)


@pytest.mark.parametrize("profile", PROFILES)
@given(msg=any_message)
@settings(max_examples=300, deadline=None)
def test_round_trip_every_message(profile: Any, msg: Message) -> None:
    codec = FrameCodec(profile)
    dec = codec.decoder()
    frames = codec.encode(msg)
    results = [dec.feed(fr) for fr in frames]
    assert all(r is None for r in results[:-1])
    back = results[-1]
    assert back is not None
    assert_close(msg, back)
    assert codec.stats.saturated == 0
    assert dec.stats.messages == 1 and dec.stats.frames == len(frames)


@pytest.mark.parametrize("profile", PROFILES)
@given(msg=any_message)
@settings(max_examples=200, deadline=None)
def test_our_encode_matches_cantools_decode(profile: Any, msg: Message) -> None:
    for fr in FrameCodec(profile).encode(msg):
        dbc_msg = DB.get_message_by_frame_id(fr.arbitration_id)
        assert dbc_msg.is_fd == fr.is_fd
        theirs = dbc_msg.decode(fr.data, decode_choices=False)
        _name, ours = decode_frame(fr)
        assert set(theirs) == set(ours)
        for key, value in theirs.items():
            assert ours[key] == pytest.approx(value, rel=1e-12, abs=1e-12), key


@pytest.mark.parametrize("profile", PROFILES)
@given(msg=any_message)
@settings(max_examples=200, deadline=None)
def test_cantools_encode_matches_our_decode(profile: Any, msg: Message) -> None:
    ours = FrameCodec(profile).encode(msg)
    dec = FrameCodec(profile).decoder()
    back = None
    for fr in ours:
        dbc_msg = DB.get_message_by_frame_id(fr.arbitration_id)
        signals = dbc_msg.decode(fr.data, decode_choices=False)
        data = dbc_msg.encode(signals, strict=False, padding=False)
        assert data == fr.data, dbc_msg.name
        back = dec.feed(Frame(fr.arbitration_id, bytes(data), dbc_msg.is_fd))
    assert back is not None
    assert_close(msg, back)


def test_profiles_frame_counts() -> None:
    m = Measurement(3, 1.0, -0.5, -0.5, 0.1, 10.0, 48.0, 0)
    c = Command(3, (4, 6, 7), (1000, 2000, 97000), 1, 7, 5000, 0)
    can, fd = FrameCodec("can"), FrameCodec("canfd")
    assert [f.arbitration_id for f in can.encode(m)] == [0x100, 0x101]
    assert [f.arbitration_id for f in can.encode(c)] == [0x110, 0x111, 0x112]
    assert all(len(f.data) <= 8 and not f.is_fd for f in can.encode(m) + can.encode(c))
    assert [(f.arbitration_id, len(f.data), f.is_fd) for f in fd.encode(m)] == [(0x108, 16, True)]
    assert [(f.arbitration_id, len(f.data), f.is_fd) for f in fd.encode(c)] == [(0x118, 20, True)]


def test_measurement_saturates_and_counts() -> None:
    codec = FrameCodec("canfd")
    back = decode_message(codec.encode(Measurement(70000, 40.0, -40.0, 0.0, -0.5, 700.0, -1.0, 0)))
    assert isinstance(back, Measurement)
    assert (back.seq, back.i_a, back.i_b, back.vdc) == (70000 - 65536, 32.767, -32.768, 0.0)
    assert back.omega_m == pytest.approx(655.34)
    assert back.theta_e == pytest.approx(2 * math.pi - 0.5, abs=1e-4)
    assert codec.stats.saturated == 4
    assert codec.stats.saturated_fields == {"i_a": 1, "i_b": 1, "omega_m": 1, "vdc": 1}
    back = decode_message(codec.encode(Measurement(0, math.inf, -math.inf, 0.0, 0.0, 0.0, 0.0, 0)))
    assert isinstance(back, Measurement) and (back.i_a, back.i_b) == (32.767, -32.768)


@pytest.mark.parametrize(
    ("msg", "field"),
    [
        (Measurement(0, math.nan, 0.0, 0.0, 0.0, 0.0, 0.0, 0), "i_a"),
        (Measurement(0, 0.0, 0.0, 0.0, math.inf, 0.0, 0.0, 0), "theta_e"),
        (Measurement(0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 256), "status"),
        (Command(0, (), (), 0, 0, 0, 0), "states"),
        (Command(0, (1, 2, 3, 4), (1, 2, 3, 4), 0, 0, 0, 0), "states"),
        (Command(0, (1, 2), (1,), 0, 0, 0, 0), "durations_ns"),
        (Command(0, (64,), (1,), 0, 0, 0, 0), "states[0]"),
        (Command(0, (1, 2), (1, 2**20), 0, 0, 0, 0), "durations_ns[1]"),
        (Command(0, (1,), (1,), 256, 0, 0, 0), "vector_id"),
        (Command(0, (1,), (1,), 0, -1, 0, 0), "candidates"),
        (Command(0, (1.5,), (1,), 0, 0, 0, 0), "states[0]"),  # type: ignore[arg-type]
        (Command(0, (1, 2, 3), (1, 2, 3), 0, 0, 0, 0, 2), "mirror"),  # type: ignore[arg-type]
        (Command(0, (1,), (1,), 0, 0, 0, 0, "yes"), "mirror"),  # type: ignore[arg-type]
        (Setpoint(True, 0, 1e39, 1), "reference"),
        (Setpoint(True, 0, math.nan, 1), "reference"),
        (Setpoint(2, 0, 1.0, 1), "enable"),  # type: ignore[arg-type]
        (ConfigParam(300, 1.0), "param_id"),
        (ConfigAck(1, 1.0, -1), "status"),
        (Heartbeat(2, 0, 0), "node"),
        (Fault(1, 0, 2**32), "detail"),
    ],
)
def test_encode_errors_name_the_field(msg: Message, field: str) -> None:
    for profile in PROFILES:
        with pytest.raises(EncodeError, match=field.replace("[", r"\[").replace("]", r"\]")):
            FrameCodec(profile).encode(msg)


def test_mirror_flag_position_and_expansion() -> None:
    c = Command(9, (0, 4, 6), (12_500, 20_000, 35_000), 17, 6, 100, 0, True)
    can = FrameCodec("can").encode(c)
    assert [len(f.data) for f in can] == [8, 8, 8]
    assert can[2].data[7] == 0x01 and can[2].data[6] == 0  # CmdC byte 7 bit 0; status byte 6
    fd = FrameCodec("canfd").encode(c)
    assert fd[0].data[19] == 0x01
    assert FrameCodec("canfd").encode(Command(9, (0, 4, 6), (1, 2, 3), mirror=False))[0].data[19] == 0
    for frames in (can, fd):
        back = decode_message(frames)
        assert isinstance(back, Command) and back.mirror is True
    states, durs = c.expanded()
    assert states == (0, 4, 6, 4, 0)
    assert durs == (12_500, 20_000, 35_000, 20_000, 12_500) and sum(durs) == 100_000
    assert Command(1, (7, 6), (10, 80), mirror=True).expanded() == ((7, 6, 7), (10, 80, 10))
    assert Command(1, (7,), (100,), mirror=True).expanded() == ((7,), (100,))
    assert Command(1, (0, 4, 6), (1, 2, 3)).expanded() == ((0, 4, 6), (1, 2, 3))
    assert back.mirror is True


def test_exec_time_is_clamped() -> None:
    for ex, want in ((2**40, 2**32 - 1), (-5, 0)):
        back = decode_message(FrameCodec("can").encode(Command(1, (1,), (10,), 0, 0, ex, 0)))
        assert isinstance(back, Command) and back.exec_time_ns == want


def test_encode_rejects_non_messages_and_bad_profile() -> None:
    with pytest.raises(EncodeError, match="not a protocol message"):
        FrameCodec("can").encode("hello")  # type: ignore[arg-type]
    with pytest.raises(ProtocolError, match="profile"):
        FrameCodec("lin")  # type: ignore[arg-type]


def test_decode_frame_strict_errors() -> None:
    with pytest.raises(DecodeError, match="0x123"):
        decode_frame(Frame(0x123, b"", False))
    with pytest.raises(DecodeError, match="MeasA: 7 data bytes, expected 8"):
        decode_frame(Frame(0x100, bytes(7), False))
    with pytest.raises(DecodeError, match=r"CmdFd\.n_states=0"):
        decode_frame(Frame(0x118, bytes(20), True))
    with pytest.raises(DecodeError, match="complete message"):
        decode_message(FrameCodec("can").encode(Measurement(1, 0, 0, 0, 0, 0, 0, 0))[:1])
    name, values = decode_frame(Frame(0x700, bytes([0, 2, 9]), False))
    assert name == "HeartbeatHost" and values == {"node": 0, "state": 2, "counter": 9}


@given(n=st.integers(1, 3))
def test_command_tuple_lengths_preserved(n: int) -> None:
    c = Command(9, tuple(range(n)), tuple(range(100, 100 + n)), 0, 0, 0, 0)
    for profile in PROFILES:
        back = decode_message(FrameCodec(profile).encode(c))
        assert back == c


@given(msg=measurements)
@settings(max_examples=50)
def test_measurement_decode_in_range(msg: Measurement) -> None:
    back = decode_message(FrameCodec("can").encode(msg))
    assert isinstance(back, Measurement) and 0.0 <= back.theta_e < 2 * math.pi


@given(c=commands())
@settings(max_examples=50)
def test_command_exact(c: Command) -> None:
    for profile in PROFILES:
        assert decode_message(FrameCodec(profile).encode(c)) == c
