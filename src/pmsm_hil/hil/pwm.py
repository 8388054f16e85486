"""Duty cycles of a centre-aligned PWM → the switching sequence the plant applies (the Python twin of
src/pmsm_hil/hil/runner/c/pwm_duty.c, integer arithmetic so both give the same ns; docs/firmware_api.md,
"Duty-cycle commands").

Carrier: a triangle counter c(t) from the valley (c = 0, every leg low) to the peak (c = 1) and back; a leg is
high (upper switch on) while c(t) > 1 − d. Single update: the carrier period is the control period Ts, the
valley at the period start: the leg is high over [t_on, Ts − t_on), t_on = (1 − d)·Ts/2, the 7 segments
0-x-xy-7-xy-x-0. Double update (control at twice the PWM rate): the carrier period is 2·Ts, an even control
period holds the rising half (high over [(1 − d)·Ts, Ts)), an odd one the falling half (high over
[0, Ts − (1 − d)·Ts)). Instants are rounded to the nearest ns (half up), the plant's time grid.
"""

from __future__ import annotations

from collections.abc import Sequence
from itertools import pairwise
from typing import Final

from pmsm_hil.protocol.codec_duty import DUTY_FULL, DUTY_NAN, DUTY_OUT_OF_RANGE, duty_raw, duty_value
from pmsm_hil.protocol.messages import Command

SINGLE: Final = 0
RISING: Final = 1
FALLING: Final = 2
#: `--pwm-update` names → the carrier half of period k: single, or double (rising on even k, falling on odd k).
PWM_UPDATES: Final = ("single", "double")


def carrier_half(pwm_update: str, k: int) -> int:
    """SINGLE, RISING or FALLING for control period k under `--pwm-update` single|double."""
    if pwm_update == "single":
        return SINGLE
    return RISING if k % 2 == 0 else FALLING


def _div_round(num: int, den: int) -> int:
    return (2 * num + den) // (2 * den)


def leg_intervals(raw: Sequence[int], ts_ns: int, half: int = SINGLE) -> list[tuple[int, int]]:
    """Per leg, the high interval [t_on, t_off) [ns] inside the period (empty when t_off <= t_on)."""
    out = []
    for r in raw:
        if not 0 <= r <= DUTY_FULL:
            raise ValueError(f"raw duty {r} outside 0..{DUTY_FULL}")
        low = DUTY_FULL - r
        if half == SINGLE:
            on = _div_round(low * ts_ns, 2 * DUTY_FULL)
            out.append((on, ts_ns - on))
        elif half == RISING:
            out.append((_div_round(low * ts_ns, DUTY_FULL), ts_ns))
        else:
            out.append((0, ts_ns - _div_round(low * ts_ns, DUTY_FULL)))
    return out


def duty_sequence(raw: Sequence[int], ts_ns: int, half: int = SINGLE) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """(states, durations_ns) of the period: leg 0 is the MSB of a state code; no zero durations; the
    durations sum to ts_ns; adjacent equal states merged (at most 2·legs + 1 segments)."""
    legs = len(raw)
    iv = leg_intervals(raw, ts_ns, half)
    bounds = sorted({0, ts_ns, *(t for pair in iv for t in pair)})
    states: list[int] = []
    durs: list[int] = []
    for a, b in pairwise(bounds):
        if b == a:
            continue
        st = 0
        for leg, (on, off) in enumerate(iv):
            if on <= a < off:
                st |= 1 << (legs - 1 - leg)
        if states and states[-1] == st:
            durs[-1] += b - a
        else:
            states.append(st)
            durs.append(b - a)
    return tuple(states), tuple(durs)


def applied_sequence(cmd: Command, ts_ns: int, half: int = SINGLE) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """(states, durations_ns) the plant applies for a Command: the carrier comparison of its duties (checked
    0..1 by the contract first), else its switching states (mirrored when it is)."""
    if cmd.duties:
        return duty_sequence([duty_raw(d) for d in cmd.duties], ts_ns, half)
    return cmd.expanded()


def duties_record(cmd: Command) -> tuple[int, tuple[float, ...]]:
    """(n_duties, 6 duties with NaN beyond n_duties) of a Command for the period record."""
    n = len(cmd.duties)
    return n, (*cmd.duties, *(_NAN,) * (6 - n))


_NAN = float("nan")

__all__ = ["DUTY_FULL", "DUTY_NAN", "DUTY_OUT_OF_RANGE", "FALLING", "PWM_UPDATES", "RISING", "SINGLE",
           "applied_sequence", "carrier_half", "duties_record", "duty_raw", "duty_sequence", "duty_value",
           "leg_intervals"]
