"""Six-phase measurement (`Measurement6`): both profiles, saturation, reassembly, errors, DBC layout."""

from __future__ import annotations

import math

import pytest

from pmsm_hil.protocol import EncodeError, FrameCodec, FrameDecoder, Measurement6, decode_frame, decode_message

M = Measurement6(513, 66.71, -33.35, -33.36, 57.76, -57.76, 0.0, 1.25, 157.08, 300.0, 0)


@pytest.mark.parametrize(("profile", "ids"), [("can", [0x102, 0x103, 0x104]), ("canfd", [0x109])])
def test_round_trip_within_quantisation(profile: str, ids: list[int]) -> None:
    codec = FrameCodec(profile)  # type: ignore[arg-type]
    frames = codec.encode(M)
    assert [f.arbitration_id for f in frames] == ids
    back = decode_message(frames)
    assert isinstance(back, Measurement6) and back.seq == 513 and back.status == 0
    for name in ("i_a", "i_b", "i_c", "i_u", "i_v", "i_w"):
        assert getattr(back, name) == pytest.approx(getattr(M, name), abs=0.005), name
    assert back.theta_e == pytest.approx(1.25, abs=1e-4) and back.vdc == pytest.approx(300.0)
    assert codec.stats.saturated == 0


def test_fd_frame_is_24_bytes_with_currents_at_10ma() -> None:
    (frame,) = FrameCodec("canfd").encode(M)
    assert len(frame.data) == 24 and frame.is_fd
    name, phys = decode_frame(frame)
    assert name == "MeasFd6" and phys["i_u"] == pytest.approx(57.76)


def test_currents_beyond_327a_saturate_and_are_counted() -> None:
    codec = FrameCodec("canfd")
    back = decode_message(codec.encode(Measurement6(70000, 400.0, -1000.0, 0.0, 0.0, 0.0, 0.0, -0.5, 0.0, 48.0)))
    assert isinstance(back, Measurement6)
    assert (back.i_a, back.i_b) == (327.67, -327.68)
    assert back.seq == 70000 & 0xFFFF and 0.0 <= back.theta_e < 2 * math.pi
    assert codec.stats.saturated_fields == {"i_a": 1, "i_b": 1}


def test_classic_parts_reassemble_out_of_order_and_not_mixed_with_three_phase() -> None:
    frames = FrameCodec("can").encode(M)
    dec = FrameDecoder()
    assert dec.feed(frames[2]) is None and dec.feed(frames[0]) is None
    got = dec.feed(frames[1])
    assert isinstance(got, Measurement6) and got.seq == 513
    assert dec.stats.out_of_order == 1
    # a three-phase MeasB never completes a six-phase measurement
    dec2 = FrameDecoder()
    three = FrameCodec("can").encode(Measurement6(7, 1, 1, 1, 1, 1, 1, 0, 0, 48))[:2]
    assert dec2.feed(three[0]) is None and dec2.feed(three[1]) is None and dec2.stats.messages == 0


@pytest.mark.parametrize(("msg", "field"), [
    (Measurement6(0, 0, 0, 0, 0, 0, 0, math.nan, 0, 0, 0), "theta_e"),
    (Measurement6(0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 256), "status"),
    (Measurement6(1.5, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0), "seq"),  # type: ignore[arg-type]
])
def test_bad_fields_raise_naming_the_field(msg: Measurement6, field: str) -> None:
    with pytest.raises(EncodeError, match=field):
        FrameCodec("can").encode(msg)
