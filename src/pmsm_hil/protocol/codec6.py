"""Six-phase measurement (`Measurement6`) frames: layouts from `hil.dbc`, raw values, message builder.

Classic CAN: Meas6A (seq, i_a, i_b, i_c), Meas6C (seq, i_u, i_v, i_w), Meas6B (seq_lo, theta_e, omega_m,
vdc, status); CAN FD: one MeasFd6 frame. Currents int16 × 0.01 A. Used by `pmsm_hil.protocol.codec`.
"""

from __future__ import annotations

from collections.abc import Callable

from pmsm_hil.protocol.errors import EncodeError
from pmsm_hil.protocol.layout import expect_layout
from pmsm_hil.protocol.messages import Measurement6

L_MEAS6_A = expect_layout("Meas6A", ("seq", "i_a", "i_b", "i_c"))
L_MEAS6_C = expect_layout("Meas6C", ("seq", "i_u", "i_v", "i_w"))
L_MEAS6_B = expect_layout("Meas6B", ("seq_lo", "theta_e", "omega_m", "vdc", "status"))
L_MEAS_FD6 = expect_layout(
    "MeasFd6", ("seq", "i_a", "i_b", "i_c", "i_u", "i_v", "i_w", "theta_e", "omega_m", "vdc", "status")
)
S_I6 = L_MEAS6_A.signal("i_a").scale
I6_LIM = (L_MEAS6_A.signal("i_a").raw_min, L_MEAS6_A.signal("i_a").raw_max)
_S_TH = L_MEAS6_B.signal("theta_e").scale
_S_W = L_MEAS6_B.signal("omega_m").scale
_S_V = L_MEAS6_B.signal("vdc").scale
_W_LIM = (L_MEAS6_B.signal("omega_m").raw_min, L_MEAS6_B.signal("omega_m").raw_max)
_V_LIM = (L_MEAS6_B.signal("vdc").raw_min, L_MEAS6_B.signal("vdc").raw_max)
_TH_MOD = L_MEAS6_B.signal("theta_e").raw_max + 1

#: Saturating converter of the owning codec: (field name, value, scale, (raw_min, raw_max)) -> raw.
Saturate = Callable[[str, float, float, tuple[int, int]], int]

_CURRENTS = ("i_a", "i_b", "i_c", "i_u", "i_v", "i_w")


def meas6_raw(m: Measurement6, sat: Saturate) -> tuple[int, ...]:
    """Raw values in MeasFd6 order; out-of-range values saturate (counted by `sat`), seq wraps."""
    try:
        th = round(m.theta_e / _S_TH) % _TH_MOD
    except (ValueError, OverflowError, TypeError):
        raise EncodeError(f"Measurement6.theta_e={m.theta_e!r} is not a finite number") from None
    try:
        seq = int(m.seq.__index__()) & 0xFFFF
    except (AttributeError, TypeError):
        raise EncodeError(f"Measurement6.seq={m.seq!r} is not an integer") from None
    status = m.status
    if status.__class__ is not int or not 0 <= status <= 255:
        raise EncodeError(f"Measurement6.status={status!r} out of range (0..255)")
    currents = [sat(name, getattr(m, name), S_I6, I6_LIM) for name in _CURRENTS]
    return (seq, *currents, th, sat("omega_m", m.omega_m, _S_W, _W_LIM), sat("vdc", m.vdc, _S_V, _V_LIM), status)


def meas6_frames_can(raw: tuple[int, ...]) -> list[tuple[int, bytes]]:
    """Classic-CAN (id, data) of the three parts, in sending order A, C, B."""
    seq, ia, ib, ic, iu, iv, iw, th, w, v, st = raw
    return [
        (L_MEAS6_A.frame_id, L_MEAS6_A.pack(seq, ia, ib, ic)),
        (L_MEAS6_C.frame_id, L_MEAS6_C.pack(seq, iu, iv, iw)),
        (L_MEAS6_B.frame_id, L_MEAS6_B.pack(seq & 0xFF, th, w, v, st)),
    ]


def meas6_from_raw(raw: tuple[int, ...]) -> Measurement6:
    """Physical message from raw values in MeasFd6 order."""
    seq, ia, ib, ic, iu, iv, iw, th, w, v, st = raw
    s = S_I6
    return Measurement6(seq, ia * s, ib * s, ic * s, iu * s, iv * s, iw * s, th * _S_TH, w * _S_W, v * _S_V, st)


def meas6_from_parts(a: tuple[int, ...], c: tuple[int, ...], b: tuple[int, ...]) -> Measurement6:
    """Physical message from the unpacked classic parts A, C, B."""
    return meas6_from_raw((a[0], a[1], a[2], a[3], c[1], c[2], c[3], b[1], b[2], b[3], b[4]))
