"""Duty-cycle Command frames (`Command.duties`): layouts from `hil.dbc`, the duty wire code, raw values and the
message builder. Classic CAN: CmdDutyA (seq, duty0..2), CmdDutyB (seq, duty3..5), CmdDutyC (seq, exec_time_ns,
status, n_duties), always three parts; CAN FD: one CmdDutyFd frame. Duties u16 × 1/65520 (d = 1 is 65520);
65534 and 65535 are the codes a sender writes for a duty outside 0..1 and for NaN, so that the host's DUT
contract reports them (docs/protocol.md, "Duty-cycle Command"). `n_duties` 0 says the sender's Command set both
forms (duties and a switching sequence): decoded with `Command.both_forms`, a finding of the host's rule `duty`.
Used by `pmsm_hil.protocol.codec`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Final

from pmsm_hil.protocol.errors import DatabaseError, EncodeError
from pmsm_hil.protocol.layout import DBC_PATH, expect_layout, locate_in_dbc
from pmsm_hil.protocol.messages import Command

L_DUTY_A = expect_layout("CmdDutyA", ("seq", "duty0", "duty1", "duty2"))
L_DUTY_B = expect_layout("CmdDutyB", ("seq", "duty3", "duty4", "duty5"))
L_DUTY_C = expect_layout("CmdDutyC", ("seq", "exec_time_ns", "status", "n_duties"))
L_DUTY_FD = expect_layout("CmdDutyFd", ("seq", "n_duties", "duty0", "duty1", "duty2", "duty3", "duty4", "duty5",
                                        "vector_id", "candidates", "exec_time_ns", "status"))

#: Raw duty of d = 1 (scale 1/65520: an edge step of Ts/131040, 0.76 ns at Ts = 100 µs).
DUTY_FULL: Final = 65520
#: Raw code for a duty below 0 or above 1.
DUTY_OUT_OF_RANGE: Final = 65534
#: Raw code for a duty that is not a number.
DUTY_NAN: Final = 65535
#: The legal duty counts of a duty-cycle Command (three-phase, dual three-phase).
N_DUTIES: Final = (3, 6)
_U32_MAX: Final = 0xFFFFFFFF

if abs(L_DUTY_A.signal("duty0").scale * DUTY_FULL - 1.0) > 1e-12:  # pragma: no cover - a DBC edit
    raise DatabaseError(locate_in_dbc(DBC_PATH, "CmdDutyA.duty0: scale is not 1/65520 (the duty wire code)"))


def duty_raw(d: float) -> int:
    """Wire code of a duty: 0..1 → round(d·65520) (half up), NaN → DUTY_NAN, outside 0..1 → DUTY_OUT_OF_RANGE."""
    if math.isnan(d):
        return DUTY_NAN
    if not 0.0 <= d <= 1.0:
        return DUTY_OUT_OF_RANGE
    return math.floor(d * DUTY_FULL + 0.5)


def duty_value(raw: int) -> float:
    """Duty of a wire code: raw/65520; NaN for DUTY_NAN, +inf for any other code above DUTY_FULL."""
    if raw <= DUTY_FULL:
        return raw / DUTY_FULL
    return math.nan if raw == DUTY_NAN else math.inf


def sets_both_forms(c: Command) -> bool:
    """The Command sets both forms: duties and a switching sequence (or was decoded so)."""
    return c.both_forms or bool(c.duties and (c.states or c.durations_ns or c.mirror))


def n_duties_wire(c: Command) -> int:
    """The `n_duties` a duty Command carries: the duty count, 0 when the Command sets both forms."""
    return 0 if sets_both_forms(c) else len(c.duties)


def _duties_raw(c: Command) -> list[int]:
    n = len(c.duties)
    if sets_both_forms(c):
        n = min(n, 6)  # sent for the record; the host's finding is the two forms
    elif n not in N_DUTIES:
        raise EncodeError(f"Command.duties has {n} entries (allowed 3 or 6)")
    out = []
    for j, d in enumerate(c.duties[:n]):
        try:
            out.append(duty_raw(float(d)))
        except (TypeError, ValueError):
            raise EncodeError(f"Command.duties[{j}]={d!r} is not a number") from None
    return out + [0] * (6 - n)


def _u8(name: str, v: object) -> int:
    if not isinstance(v, int) or not 0 <= v <= 255:
        raise EncodeError(f"Command.{name}={v!r} out of range (0..255)")
    return v


def _exec(v: object) -> int:
    if not isinstance(v, int):
        raise EncodeError(f"Command.exec_time_ns={v!r} is not an integer")
    return 0 if v < 0 else _U32_MAX if v > _U32_MAX else v


def _seq(v: object) -> int:
    if not isinstance(v, int):
        raise EncodeError(f"Command.seq={v!r} is not an integer")
    return v & 0xFFFF


def raw_fd(c: Command) -> tuple[int, ...]:
    """Raw values in CmdDutyFd order."""
    r = _duties_raw(c)
    return (_seq(c.seq), n_duties_wire(c), *r, _u8("vector_id", c.vector_id), _u8("candidates", c.candidates),
            _exec(c.exec_time_ns), _u8("status", c.status))


def raw_parts(c: Command) -> tuple[tuple[int, ...], tuple[int, ...], tuple[int, ...]]:
    """Raw values of CmdDutyA, CmdDutyB, CmdDutyC (no vector_id or candidates in the classic form)."""
    r = _duties_raw(c)
    seq = _seq(c.seq)
    _u8("vector_id", c.vector_id)
    _u8("candidates", c.candidates)
    return ((seq, r[0], r[1], r[2]), (seq, r[3], r[4], r[5]),
            (seq, _exec(c.exec_time_ns), _u8("status", c.status), n_duties_wire(c)))


def command(seq: int, n: int, raw: Sequence[int], vid: int, cand: int, ex: int, st: int) -> Command:
    """The Command of decoded raw values (n: n_duties). A count other than 3 or 6 is kept as the length of
    `duties` (NaN beyond the six the frames carry) for the host's `duty` finding; 0: the sender set both forms
    (`both_forms`, no duties)."""
    if n == 0:
        return Command(seq=seq, states=(), durations_ns=(), vector_id=vid, candidates=cand, exec_time_ns=ex,
                       status=st, both_forms=True)
    duties = tuple(duty_value(r) for r in raw[:n]) + (math.nan,) * max(0, n - len(raw))
    return Command(seq=seq, states=(), durations_ns=(), vector_id=vid, candidates=cand, exec_time_ns=ex, status=st,
                   duties=duties)


__all__ = ["DUTY_FULL", "DUTY_NAN", "DUTY_OUT_OF_RANGE", "L_DUTY_A", "L_DUTY_B", "L_DUTY_C", "L_DUTY_FD",
           "N_DUTIES", "command", "duty_raw", "duty_value", "n_duties_wire", "raw_fd", "raw_parts",
           "sets_both_forms"]
