"""The DUT contract of duty-cycle Commands (src/pmsm_hil/hil/runner/contract.py `check_duties`): NaN, out-of-range and a
duty count other than the machine's legs are findings of rule `duty`; valid duties pass, whatever the durations."""

from __future__ import annotations

import math

import pytest

from pmsm_hil.hil.runner.contract import BOTH_FORMS_ON_WIRE, DUTY, check_command, describe
from pmsm_hil.protocol.codec import FrameCodec, decode_message
from pmsm_hil.protocol.codec_duty import DUTY_NAN, DUTY_OUT_OF_RANGE, duty_raw, duty_value
from pmsm_hil.protocol.messages import Command


def _cmd(*duties: float) -> Command:
    return Command(seq=7, states=(), durations_ns=(), duties=duties)


@pytest.mark.parametrize(("duties", "max_state", "detail"), [
    ((0.5, math.nan, 0.5), 7, "duty 1 is NaN"),
    ((0.5, 0.5, 1.2), 7, "duty 2 = 1.2 outside 0..1"),
    ((-0.1, 0.5, 0.5), 7, "duty 0 = -0.1 outside 0..1"),
    ((0.5, math.inf, 0.5), 7, "duty 1 = inf outside 0..1"),
    ((0.5, 0.5, 0.5), 63, "3 duties for a machine with 6 legs"),
    ((0.5,) * 6, 7, "6 duties for a machine with 3 legs"),
])
def test_bad_duties_are_duty_findings(duties: tuple[float, ...], max_state: int, detail: str) -> None:
    assert check_command(_cmd(*duties), 100_000, max_state) == (DUTY, detail)


def test_both_forms_at_once_are_a_duty_finding() -> None:
    both = Command(seq=7, states=(7, 0), durations_ns=(50_000, 50_000), duties=(0.5, 0.5, 0.5))
    assert check_command(both, 100_000, 7) == (
        DUTY, "both forms set: 3 duties and a switching sequence of 2 state(s); a Command carries one")


@pytest.mark.parametrize("profile", ["can", "canfd"])
def test_both_forms_survive_the_wire_as_a_duty_finding(profile: str) -> None:
    """A sender whose Command sets both forms sends a duty Command with n_duties 0 (the target core does the same
    for its C firmware's): decoded with `both_forms`, a `duty` finding, never one form taken silently."""
    from pmsm_hil.protocol.codec_duty import L_DUTY_C, L_DUTY_FD

    both = Command(seq=7, states=(7, 0), durations_ns=(50_000, 50_000), duties=(0.5, 0.5, 0.5))
    frames = FrameCodec(profile).encode(both)
    layout = L_DUTY_FD if profile == "canfd" else L_DUTY_C
    n_at = layout.index("n_duties")
    assert [layout.unpack(f[1])[n_at] for f in frames if f[0] == layout.frame_id] == [0]
    from pmsm_hil.protocol.codec import FrameDecoder

    dec = FrameDecoder()
    got = [m for m in (dec.feed(fr) for fr in frames) if m is not None]
    assert len(got) == 1
    back = got[0]
    assert isinstance(back, Command) and back.both_forms and back.seq == 7 and back.duties == ()
    assert check_command(back, 100_000, 7) == (DUTY, BOTH_FORMS_ON_WIRE)
    assert describe(back) == "Command seq=7 n_duties=0 (both forms)"


@pytest.mark.parametrize(("profile", "n"), [("can", 4), ("canfd", 4), ("can", 200), ("canfd", 200)])
def test_a_duty_count_of_no_machine_decodes_to_a_duty_finding(profile: str, n: int) -> None:
    """n_duties 4 or 200 on the wire: the host decodes the Command (not a rejected frame, which would end as a
    missing Command) and finds it wrong by rule `duty`."""
    from pmsm_hil.protocol.codec import FrameDecoder
    from pmsm_hil.protocol.codec_duty import L_DUTY_C, L_DUTY_FD

    frames = FrameCodec(profile).encode(_cmd(0.5, 0.5, 0.5))
    patched = []
    for fr in frames:
        if fr[0] == L_DUTY_FD.frame_id:
            raw = list(L_DUTY_FD.unpack(fr[1]))
            raw[1] = n
            fr = type(fr)(fr[0], L_DUTY_FD.pack(*raw), fr[2])
        elif fr[0] == L_DUTY_C.frame_id:
            raw = list(L_DUTY_C.unpack(fr[1]))
            raw[3] = n
            fr = type(fr)(fr[0], L_DUTY_C.pack(*raw), fr[2])
        patched.append(fr)
    dec = FrameDecoder()
    got = [m for m in (dec.feed(fr) for fr in patched) if m is not None]
    assert len(got) == 1 and isinstance(got[0], Command) and len(got[0].duties) == n
    assert check_command(got[0], 100_000, 7) == (DUTY, f"{n} duties for a machine with 3 legs")
    assert describe(got[0]).endswith(f", … {n} in all)") == (n > 6)


def test_valid_duties_pass_and_are_described() -> None:
    assert check_command(_cmd(0.0, 0.5, 1.0), 100_000, 7) is None
    assert check_command(_cmd(*(0.1 * j for j in range(6))), 100_000, 63) is None
    assert describe(_cmd(0.25, 0.5, 1.0)) == "Command seq=7 duties=(0.25, 0.5, 1)"


@pytest.mark.parametrize("profile", ["can", "canfd"])
def test_bad_duties_survive_the_wire_as_findings(profile: str) -> None:
    """A sender never clamps: NaN and out-of-range duties reach the host as NaN / +inf (reserved codes)."""
    back = decode_message(FrameCodec(profile).encode(_cmd(0.3, math.nan, 7.0)))
    assert isinstance(back, Command)
    assert back.duties[0] == duty_value(duty_raw(0.3)) and math.isnan(back.duties[1]) and back.duties[2] == math.inf
    assert check_command(back, 100_000, 7) == (DUTY, "duty 1 is NaN")
    assert (duty_raw(math.nan), duty_raw(-1e-9), duty_raw(1.0 + 1e-9)) == (DUTY_NAN, DUTY_OUT_OF_RANGE,
                                                                           DUTY_OUT_OF_RANGE)
