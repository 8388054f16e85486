"""Hot-path frame codec: logical messages <-> frames, with layouts compiled from `hil.dbc`.

Encoding policy: a Measurement saturates out-of-range values to the nearest representable raw value
and counts it in `FrameCodec.stats` (what a real ADC does); `seq` wraps mod 2^16 and `theta_e` wraps
into [0, 2π). Every other message raises EncodeError naming the field when a value is out of range;
the exceptions are `Command.exec_time_ns`, which is clamped to [0, 2^32 - 1], and `ConfigAck.value`, which
echoes any ConfigParam value, NaN and ±inf included (a target rejects them with status 5). The decoder never
raises: bad frames are counted in `FrameDecoder.stats`. `decode_frame` is the strict API for tools.
"""

from __future__ import annotations

import dataclasses
import math
import operator
import struct
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, Literal, TypeVar

from pmsm_hil.errors import HilError
from pmsm_hil.protocol import codec6, codec_duty
from pmsm_hil.protocol.assembler import Assembler, DecodeStats
from pmsm_hil.protocol.errors import DecodeError, EncodeError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.layout import FrameLayout, expect_layout, load_layouts
from pmsm_hil.protocol.messages import (
    Command,
    ConfigAck,
    ConfigParam,
    Fault,
    Heartbeat,
    Measurement,
    Measurement6,
    Message,
    Setpoint,
)

Profile = Literal["can", "canfd"]
PROFILES: tuple[Profile, ...] = ("can", "canfd")
MAX_STATES = 3

_L = load_layouts()


_CMD_PACKED = ("state0", "state1", "state2", "n_states", "duration0")
L_MEAS_A = expect_layout("MeasA", ("seq", "i_a", "i_b", "i_c"))
L_MEAS_B = expect_layout("MeasB", ("seq_lo", "theta_e", "omega_m", "vdc", "status"))
L_MEAS_FD = expect_layout("MeasFd", ("seq", "i_a", "i_b", "i_c", "theta_e", "omega_m", "vdc", "status"))
L_CMD_A = expect_layout("CmdA", ("seq", *_CMD_PACKED, "vector_id"))
L_CMD_B = expect_layout("CmdB", ("seq", "duration1", "duration2", "candidates"))
L_CMD_C = expect_layout("CmdC", ("seq", "exec_time_ns", "status", "mirror"))
L_CMD_FD = expect_layout(
    "CmdFd",
    ("seq", *_CMD_PACKED, "duration1", "duration2", "vector_id", "candidates", "exec_time_ns", "status", "mirror"),
)
L_SETPOINT = expect_layout("Setpoint", ("enable", "mode", "reference", "controller_id"))
L_CONFIG = expect_layout("ConfigParam", ("param_id", "value"))
L_CONFIG_ACK = expect_layout("ConfigAck", ("param_id", "value", "status"))
L_FAULT = (
    expect_layout("FaultHost", ("node", "code", "detail")),
    expect_layout("FaultTarget", ("node", "code", "detail")),
)
L_HEARTBEAT = (
    expect_layout("HeartbeatHost", ("node", "state", "counter")),
    expect_layout("HeartbeatTarget", ("node", "state", "counter")),
)

_S_I = L_MEAS_A.signal("i_a").scale
_S_TH = L_MEAS_B.signal("theta_e").scale
_S_W = L_MEAS_B.signal("omega_m").scale
_S_V = L_MEAS_B.signal("vdc").scale
_I_LIM = (L_MEAS_A.signal("i_a").raw_min, L_MEAS_A.signal("i_a").raw_max)
_W_LIM = (L_MEAS_B.signal("omega_m").raw_min, L_MEAS_B.signal("omega_m").raw_max)
_V_LIM = (L_MEAS_B.signal("vdc").raw_min, L_MEAS_B.signal("vdc").raw_max)
_TH_MOD = L_MEAS_B.signal("theta_e").raw_max + 1
_STATE_MAX = L_CMD_A.signal("state0").raw_max
_DUR_MAX = L_CMD_A.signal("duration0").raw_max
#: Longest sub-interval a Command can carry [ns] (the DBC's duration fields): a period Ts above it cannot be sent
MAX_DURATION_NS: int = _DUR_MAX
_U32_MAX = L_CMD_C.signal("exec_time_ns").raw_max
_F32 = struct.Struct("<f")
_T = TypeVar("_T")


@dataclass(slots=True)
class EncodeStats:
    """Counters of a FrameCodec: measurement fields saturated on encode (by field name)."""

    saturated: int = 0
    saturated_fields: dict[str, int] = field(default_factory=dict)


def _bad(field_name: str, value: object, allowed: str) -> EncodeError:
    return EncodeError(f"{field_name}={value!r} out of range ({allowed})")


def _u(field_name: str, value: Any, hi: int) -> int:
    """Strict unsigned integer in [0, hi]."""
    try:
        v = operator.index(value)
    except TypeError:
        raise EncodeError(f"{field_name}={value!r} is not an integer") from None
    if not 0 <= v <= hi:
        raise _bad(field_name, value, f"0..{hi}")
    return int(v)


def _int(field_name: str, value: Any) -> int:
    """Any integer (wrapped by the caller)."""
    try:
        return int(operator.index(value))
    except TypeError:
        raise EncodeError(f"{field_name}={value!r} is not an integer") from None


def _f32(field_name: str, value: object, *, finite: bool = True) -> float:
    """Strict float32 value, finite unless `finite` is False (an echo: NaN and ±inf pass)."""
    try:
        x = float(value)  # type: ignore[arg-type]
        _F32.pack(x)
    except (TypeError, ValueError, OverflowError):
        raise EncodeError(f"{field_name}={value!r} is not representable as float32") from None
    if finite and not math.isfinite(x):
        raise EncodeError(f"{field_name}={value!r} is not finite")
    return x


class FrameCodec:
    """Encodes messages into frames for one profile ("can": classic ≤ 8 bytes; "canfd": one frame each
    way for Measurement and Command) and hands out decoders."""

    def __init__(self, profile: Profile) -> None:
        if profile not in PROFILES:
            raise EncodeError(f"profile={profile!r} unknown (expected one of {PROFILES})")
        self.profile: Profile = profile
        self.stats = EncodeStats()
        fd = profile == "canfd"
        self._encoders: dict[type, Callable[[Any], list[Frame]]] = {
            Measurement: self._enc_meas_fd if fd else self._enc_meas_can,
            Measurement6: self._enc_meas6_fd if fd else self._enc_meas6_can,
            Command: self._enc_cmd_fd if fd else self._enc_cmd_can,
            Setpoint: _enc_setpoint,
            ConfigParam: _enc_config,
            ConfigAck: _enc_config_ack,
            Heartbeat: _enc_heartbeat,
            Fault: _enc_fault,
        }

    def encode(self, msg: Message) -> list[Frame]:
        """Frames for `msg`, in sending order; raises EncodeError naming the field on bad values."""
        enc = self._encoders.get(type(msg))
        if enc is None:
            raise EncodeError(f"message type {type(msg).__name__} is not a protocol message")
        return enc(msg)

    def decoder(self, *, ordered: bool = True) -> FrameDecoder:
        """A new stateful decoder (it accepts the frames of both profiles); `ordered=False` for the host's
        Commands (see `Assembler`)."""
        return FrameDecoder(ordered=ordered)

    # -- measurement (saturating) --
    def _sat(self, name: str, x: float, scale: float, lim: tuple[int, int]) -> int:
        try:
            r = round(x / scale)
        except OverflowError:
            r = lim[1] if x > 0 else lim[0]
        except ValueError:
            raise EncodeError(f"Measurement.{name}={x!r} is not a number") from None
        except TypeError:
            raise EncodeError(f"Measurement.{name}={x!r} is not a number") from None
        if lim[0] <= r <= lim[1]:
            return r
        self.stats.saturated += 1
        self.stats.saturated_fields[name] = self.stats.saturated_fields.get(name, 0) + 1
        return lim[0] if r < lim[0] else lim[1]

    def _meas_raw(self, m: Measurement) -> tuple[int, int, int, int, int, int, int, int]:
        """Raw values; fast path when everything is in range, else the per-field slow path."""
        seq, st = m.seq, m.status
        try:
            ia, ib, ic = round(m.i_a / _S_I), round(m.i_b / _S_I), round(m.i_c / _S_I)
            w, v = round(m.omega_m / _S_W), round(m.vdc / _S_V)
            th = round(m.theta_e / _S_TH) % _TH_MOD
        except (ValueError, OverflowError, TypeError):
            return self._meas_raw_slow(m)
        if (
            _I_LIM[0] <= ia <= _I_LIM[1]
            and _I_LIM[0] <= ib <= _I_LIM[1]
            and _I_LIM[0] <= ic <= _I_LIM[1]
            and _W_LIM[0] <= w <= _W_LIM[1]
            and _V_LIM[0] <= v <= _V_LIM[1]
            and seq.__class__ is int
            and 0 <= seq <= 0xFFFF
            and st.__class__ is int
            and 0 <= st <= 255
        ):
            return seq, ia, ib, ic, th, w, v, st
        return self._meas_raw_slow(m)

    def _meas_raw_slow(self, m: Measurement) -> tuple[int, int, int, int, int, int, int, int]:
        sat = self._sat
        try:
            th = round(m.theta_e / _S_TH) % _TH_MOD
        except (ValueError, OverflowError, TypeError):
            raise EncodeError(f"Measurement.theta_e={m.theta_e!r} is not a finite number") from None
        seq = _int("Measurement.seq", m.seq) & 0xFFFF
        return (
            seq,
            sat("i_a", m.i_a, _S_I, _I_LIM),
            sat("i_b", m.i_b, _S_I, _I_LIM),
            sat("i_c", m.i_c, _S_I, _I_LIM),
            th,
            sat("omega_m", m.omega_m, _S_W, _W_LIM),
            sat("vdc", m.vdc, _S_V, _V_LIM),
            _u("Measurement.status", m.status, 255),
        )

    def _enc_meas_can(self, m: Measurement) -> list[Frame]:
        seq, ia, ib, ic, th, w, v, st = self._meas_raw(m)
        return [
            Frame(L_MEAS_A.frame_id, L_MEAS_A.pack(seq, ia, ib, ic), False),
            Frame(L_MEAS_B.frame_id, L_MEAS_B.pack(seq & 0xFF, th, w, v, st), False),
        ]

    def _enc_meas_fd(self, m: Measurement) -> list[Frame]:
        return [Frame(L_MEAS_FD.frame_id, L_MEAS_FD.pack(*self._meas_raw(m)), True)]

    def _enc_meas6_can(self, m: Measurement6) -> list[Frame]:
        return [Frame(i, d, False) for i, d in codec6.meas6_frames_can(codec6.meas6_raw(m, self._sat))]

    def _enc_meas6_fd(self, m: Measurement6) -> list[Frame]:
        lay = codec6.L_MEAS_FD6
        return [Frame(lay.frame_id, lay.pack(*codec6.meas6_raw(m, self._sat)), True)]

    # -- command (strict) --
    def _enc_cmd_can(self, c: Command) -> list[Frame]:
        if c.duties or c.both_forms:
            a, b, cc = codec_duty.raw_parts(c)
            return [Frame(codec_duty.L_DUTY_A.frame_id, codec_duty.L_DUTY_A.pack(*a), False),
                    Frame(codec_duty.L_DUTY_B.frame_id, codec_duty.L_DUTY_B.pack(*b), False),
                    Frame(codec_duty.L_DUTY_C.frame_id, codec_duty.L_DUTY_C.pack(*cc), False)]
        seq, s0, s1, s2, n, d0, d1, d2, vid, cand, ex, st, mir = _cmd_raw(c)
        return [
            Frame(L_CMD_A.frame_id, L_CMD_A.pack(seq, s0, s1, s2, n, d0, vid), False),
            Frame(L_CMD_B.frame_id, L_CMD_B.pack(seq, d1, d2, cand), False),
            Frame(L_CMD_C.frame_id, L_CMD_C.pack(seq, ex, st, mir), False),
        ]

    def _enc_cmd_fd(self, c: Command) -> list[Frame]:
        if c.duties or c.both_forms:
            return [Frame(codec_duty.L_DUTY_FD.frame_id, codec_duty.L_DUTY_FD.pack(*codec_duty.raw_fd(c)), True)]
        return [Frame(L_CMD_FD.frame_id, L_CMD_FD.pack(*_cmd_raw(c)), True)]


def _cmd_raw(c: Command) -> tuple[int, ...]:
    """Raw values; fast path when every field is a plain in-range int, else the checking slow path."""
    states, durs = c.states, c.durations_ns
    n = len(states)
    seq, vid, cand, ex, st, mir = c.seq, c.vector_id, c.candidates, c.exec_time_ns, c.status, c.mirror
    if (
        1 <= n <= 3
        and (mir is False or mir is True)
        and len(durs) == n
        and seq.__class__ is int
        and 0 <= seq <= 0xFFFF
        and vid.__class__ is int
        and 0 <= vid <= 255
        and cand.__class__ is int
        and 0 <= cand <= 255
        and st.__class__ is int
        and 0 <= st <= 255
        and ex.__class__ is int
        and 0 <= ex <= _U32_MAX
    ):
        for k in range(n):
            sk, dk = states[k], durs[k]
            if not (sk.__class__ is int and 0 <= sk <= _STATE_MAX and dk.__class__ is int and 0 <= dk <= _DUR_MAX):
                return _cmd_raw_slow(c)
        s_pad = (*states, 0, 0)
        d_pad = (*durs, 0, 0)
        return seq, s_pad[0], s_pad[1], s_pad[2], n, d_pad[0], d_pad[1], d_pad[2], vid, cand, ex, st, int(mir)
    return _cmd_raw_slow(c)


def _cmd_raw_slow(c: Command) -> tuple[int, ...]:
    n = len(c.states)
    if not 1 <= n <= MAX_STATES:
        raise EncodeError(f"Command.states has {n} entries (allowed 1..{MAX_STATES})")
    if len(c.durations_ns) != n:
        raise EncodeError(f"Command.durations_ns has {len(c.durations_ns)} entries, states has {n}")
    st = [_u(f"Command.states[{j}]", s, _STATE_MAX) for j, s in enumerate(c.states)]
    du = [_u(f"Command.durations_ns[{j}]", d, _DUR_MAX) for j, d in enumerate(c.durations_ns)]
    st += [0] * (MAX_STATES - n)
    du += [0] * (MAX_STATES - n)
    ex = _int("Command.exec_time_ns", c.exec_time_ns)
    ex = 0 if ex < 0 else _U32_MAX if ex > _U32_MAX else ex
    return (
        _int("Command.seq", c.seq) & 0xFFFF,
        st[0],
        st[1],
        st[2],
        n,
        du[0],
        du[1],
        du[2],
        _u("Command.vector_id", c.vector_id, 255),
        _u("Command.candidates", c.candidates, 255),
        ex,
        _u("Command.status", c.status, 255),
        _flag("Command.mirror", c.mirror),
    )


def _flag(field_name: str, value: object) -> int:
    """Strict one-bit flag: a bool, or the integers 0 and 1."""
    if value is True or value is False:
        return int(value)
    if isinstance(value, int) and value in (0, 1):
        return int(value)
    raise EncodeError(f"{field_name}={value!r} is not a flag (False/True or 0/1)")


def _enc_setpoint(s: Setpoint) -> list[Frame]:
    if not isinstance(s.enable, (bool, int)) or s.enable not in (0, 1):
        raise EncodeError(f"Setpoint.enable={s.enable!r} is not a bool")
    data = L_SETPOINT.pack(
        int(s.enable),
        _u("Setpoint.mode", s.mode, 255),
        _f32("Setpoint.reference", s.reference),
        _u("Setpoint.controller_id", s.controller_id, 255),
    )
    return [Frame(L_SETPOINT.frame_id, data, False)]


def _enc_config(c: ConfigParam) -> list[Frame]:
    data = L_CONFIG.pack(_u("ConfigParam.param_id", c.param_id, 255), _f32("ConfigParam.value", c.value))
    return [Frame(L_CONFIG.frame_id, data, False)]


def _enc_config_ack(c: ConfigAck) -> list[Frame]:
    data = L_CONFIG_ACK.pack(
        _u("ConfigAck.param_id", c.param_id, 255),
        _f32("ConfigAck.value", c.value, finite=False),  # the echo of any ConfigParam, also a rejected NaN
        _u("ConfigAck.status", c.status, 255),
    )
    return [Frame(L_CONFIG_ACK.frame_id, data, False)]


def _node_layout(layouts: tuple[FrameLayout, FrameLayout], kind: str, node: Any) -> FrameLayout:
    if node not in (0, 1) or isinstance(node, float):
        raise EncodeError(f"{kind}.node={node!r} out of range (0 host, 1 target)")
    return layouts[int(node)]


def _enc_heartbeat(h: Heartbeat) -> list[Frame]:
    lay = _node_layout(L_HEARTBEAT, "Heartbeat", h.node)
    data = lay.pack(int(h.node), _u("Heartbeat.state", h.state, 255), _u("Heartbeat.counter", h.counter, 255))
    return [Frame(lay.frame_id, data, False)]


def _enc_fault(f: Fault) -> list[Frame]:
    lay = _node_layout(L_FAULT, "Fault", f.node)
    data = lay.pack(int(f.node), _u("Fault.code", f.code, 255), _u("Fault.detail", f.detail, _U32_MAX))
    return [Frame(lay.frame_id, data, False)]


# ---------------------------------------------------------------- decoding


def _builder(cls: type[_T]) -> Callable[..., _T]:
    """Fast constructor of a frozen slots dataclass from positional field values.

    Sets the slots through their descriptors (about half the cost of the frozen __init__, which calls
    object.__setattr__ per field); the messages have no __post_init__, so the result is identical."""
    names = [f.name for f in dataclasses.fields(cls)]  # type: ignore[arg-type]
    ns: dict[str, Any] = {"_new": object.__new__, "_cls": cls}
    for i, name in enumerate(names):
        ns[f"_s{i}"] = cls.__dict__[name].__set__
    args = ", ".join(f"a{i}" for i in range(len(names)))
    body = "; ".join(f"_s{i}(o, a{i})" for i in range(len(names)))
    exec(f"def build({args}):\n    o = _new(_cls); {body}\n    return o", ns)  # fixed template, no input
    return ns["build"]  # type: ignore[no-any-return]


_new_meas = _builder(Measurement)
_new_cmd = _builder(Command)


class _BadValueError(HilError):
    """Internal: a frame carries an impossible value (e.g. n_states = 0)."""


def _meas(seq: int, ia: int, ib: int, ic: int, th: int, w: int, v: int, st: int) -> Measurement:
    return _new_meas(seq, ia * _S_I, ib * _S_I, ic * _S_I, th * _S_TH, w * _S_W, v * _S_V, st)


def _cmd(
    seq: int,
    s0: int,
    s1: int,
    s2: int,
    n: int,
    d0: int,
    d1: int,
    d2: int,
    vid: int,
    cand: int,
    ex: int,
    st: int,
    mir: int,
) -> Command:
    m = mir == 1
    if n == 3:
        return _new_cmd(seq, (s0, s1, s2), (d0, d1, d2), vid, cand, ex, st, m, (), False)
    if n == 2:
        return _new_cmd(seq, (s0, s1), (d0, d1), vid, cand, ex, st, m, (), False)
    if n == 1:
        return _new_cmd(seq, (s0,), (d0,), vid, cand, ex, st, m, (), False)
    raise _BadValueError(f"n_states={n} (allowed 1..{MAX_STATES})")


class FrameDecoder:
    """Stateful decoder: `feed` one frame, get a complete message or None. Never raises on bad frames;
    see `stats` (DecodeStats) for what was dropped and why."""

    def __init__(self, *, ordered: bool = True) -> None:
        self.stats = DecodeStats()
        st = self.stats
        self._meas = Assembler(2, st, ordered=ordered)
        self._meas_fd = Assembler(1, st, ordered=ordered)
        self._cmd = Assembler(3, st, ordered=ordered)
        self._cmd_fd = Assembler(1, st, ordered=ordered)
        self._duty = Assembler(3, st, ordered=ordered)
        self._duty_fd = Assembler(1, st, ordered=ordered)
        self._meas6 = Assembler(3, st, ordered=ordered)
        self._meas6_fd = Assembler(1, st, ordered=ordered)
        h: dict[int, tuple[int, Callable[[bytes], Message | None]]] = {
            L_MEAS_A.frame_id: (L_MEAS_A.length, self._meas_a),
            L_MEAS_B.frame_id: (L_MEAS_B.length, self._meas_b),
            L_MEAS_FD.frame_id: (L_MEAS_FD.length, self._meas_fd1),
            L_CMD_A.frame_id: (L_CMD_A.length, self._cmd_a),
            L_CMD_B.frame_id: (L_CMD_B.length, self._cmd_b),
            L_CMD_C.frame_id: (L_CMD_C.length, self._cmd_c),
            L_CMD_FD.frame_id: (L_CMD_FD.length, self._cmd_fd1),
            codec_duty.L_DUTY_A.frame_id: (codec_duty.L_DUTY_A.length, self._duty_a),
            codec_duty.L_DUTY_B.frame_id: (codec_duty.L_DUTY_B.length, self._duty_b),
            codec_duty.L_DUTY_C.frame_id: (codec_duty.L_DUTY_C.length, self._duty_c),
            codec_duty.L_DUTY_FD.frame_id: (codec_duty.L_DUTY_FD.length, self._duty_fd1),
            codec6.L_MEAS6_A.frame_id: (codec6.L_MEAS6_A.length, self._meas6_a),
            codec6.L_MEAS6_C.frame_id: (codec6.L_MEAS6_C.length, self._meas6_c),
            codec6.L_MEAS6_B.frame_id: (codec6.L_MEAS6_B.length, self._meas6_b),
            codec6.L_MEAS_FD6.frame_id: (codec6.L_MEAS_FD6.length, self._meas6_fd1),
        }
        for lay, simple in _SIMPLE.items():
            h[lay.frame_id] = (lay.length, _simple(lay, simple))
        self._handlers = h

    def restart(self) -> None:
        """Start the sequence tracking afresh (a new run): a Measurement seq lower than the last one is then
        accepted instead of counted as stale. The statistics are kept."""
        for assembler in (self._meas, self._meas_fd, self._cmd, self._cmd_fd, self._meas6, self._meas6_fd,
                          self._duty, self._duty_fd):
            assembler.restart()

    def feed(self, frame: Frame) -> Message | None:
        """Offer one frame; returns a message when all its parts for one seq have arrived."""
        st = self.stats
        st.frames += 1
        entry = self._handlers.get(frame[0])
        if entry is None:
            st.unknown_id += 1
            return None
        data = frame[1]
        if len(data) != entry[0]:
            st.bad_length += 1
            return None
        try:
            msg = entry[1](data)
        except _BadValueError:
            st.bad_value += 1
            return None
        if msg is not None:
            st.messages += 1
        return msg

    def _meas_part(self, part: int, layout: FrameLayout, mask: int, data: bytes) -> Message | None:
        raw = layout.unpack(data)
        parts = self._meas.add(part, raw[0], mask, raw)
        if parts is None:
            return None
        a, b = parts
        return _meas(a[0], a[1], a[2], a[3], b[1], b[2], b[3], b[4])

    def _meas_a(self, data: bytes) -> Message | None:
        return self._meas_part(0, L_MEAS_A, 0xFFFF, data)

    def _meas_b(self, data: bytes) -> Message | None:
        return self._meas_part(1, L_MEAS_B, 0xFF, data)

    def _meas_fd1(self, data: bytes) -> Message | None:
        raw = L_MEAS_FD.unpack(data)
        return None if self._meas_fd.add(0, raw[0], 0xFFFF, raw) is None else _meas(*raw)

    def _meas6_part(self, part: int, layout: FrameLayout, mask: int, data: bytes) -> Message | None:
        raw = layout.unpack(data)
        parts = self._meas6.add(part, raw[0], mask, raw)
        return None if parts is None else codec6.meas6_from_parts(parts[0], parts[1], parts[2])

    def _meas6_a(self, data: bytes) -> Message | None:
        return self._meas6_part(0, codec6.L_MEAS6_A, 0xFFFF, data)

    def _meas6_c(self, data: bytes) -> Message | None:
        return self._meas6_part(1, codec6.L_MEAS6_C, 0xFFFF, data)

    def _meas6_b(self, data: bytes) -> Message | None:
        return self._meas6_part(2, codec6.L_MEAS6_B, 0xFF, data)

    def _meas6_fd1(self, data: bytes) -> Message | None:
        raw = codec6.L_MEAS_FD6.unpack(data)
        return None if self._meas6_fd.add(0, raw[0], 0xFFFF, raw) is None else codec6.meas6_from_raw(raw)

    def _cmd_part(self, part: int, layout: FrameLayout, data: bytes) -> Message | None:
        raw = layout.unpack(data)
        if part == 0 and not 1 <= raw[4] <= MAX_STATES:
            raise _BadValueError(f"CmdA.n_states={raw[4]}")
        parts = self._cmd.add(part, raw[0], 0xFFFF, raw)
        if parts is None:
            return None
        a, b, c = parts
        return _cmd(a[0], a[1], a[2], a[3], a[4], a[5], b[1], b[2], a[6], b[3], c[1], c[2], c[3])

    def _cmd_a(self, data: bytes) -> Message | None:
        return self._cmd_part(0, L_CMD_A, data)

    def _cmd_b(self, data: bytes) -> Message | None:
        return self._cmd_part(1, L_CMD_B, data)

    def _cmd_c(self, data: bytes) -> Message | None:
        return self._cmd_part(2, L_CMD_C, data)

    def _cmd_fd1(self, data: bytes) -> Message | None:
        raw = L_CMD_FD.unpack(data)
        if not 1 <= raw[4] <= MAX_STATES:
            raise _BadValueError(f"CmdFd.n_states={raw[4]}")
        return None if self._cmd_fd.add(0, raw[0], 0xFFFF, raw) is None else _cmd(*raw)

    def _duty_part(self, part: int, layout: FrameLayout, data: bytes) -> Message | None:
        raw = layout.unpack(data)
        parts = self._duty.add(part, raw[0], 0xFFFF, raw)
        if parts is None:
            return None
        a, b, c = parts
        return codec_duty.command(a[0], c[3], (*a[1:], *b[1:]), 0, 0, c[1], c[2])

    def _duty_a(self, data: bytes) -> Message | None:
        return self._duty_part(0, codec_duty.L_DUTY_A, data)

    def _duty_b(self, data: bytes) -> Message | None:
        return self._duty_part(1, codec_duty.L_DUTY_B, data)

    def _duty_c(self, data: bytes) -> Message | None:
        return self._duty_part(2, codec_duty.L_DUTY_C, data)

    def _duty_fd1(self, data: bytes) -> Message | None:
        raw = codec_duty.L_DUTY_FD.unpack(data)
        if self._duty_fd.add(0, raw[0], 0xFFFF, raw) is None:
            return None
        return codec_duty.command(raw[0], raw[1], raw[2:8], raw[8], raw[9], raw[10], raw[11])


_SIMPLE: dict[FrameLayout, Callable[..., Message]] = {
    L_SETPOINT: lambda en, mode, ref, cid: Setpoint(bool(en), mode, ref, cid),
    L_CONFIG: ConfigParam,
    L_CONFIG_ACK: ConfigAck,
    L_FAULT[0]: Fault,
    L_FAULT[1]: Fault,
    L_HEARTBEAT[0]: Heartbeat,
    L_HEARTBEAT[1]: Heartbeat,
}


def _simple(layout: FrameLayout, build: Callable[..., Message]) -> Callable[[bytes], Message | None]:
    unpack = layout.unpack

    def handler(data: bytes) -> Message | None:
        return build(*unpack(data))

    return handler


# ---------------------------------------------------------------- strict API for tools

_BY_ID: dict[int, FrameLayout] = {lay.frame_id: lay for lay in _L.values()}


def layout_for_id(arbitration_id: int) -> FrameLayout | None:
    """The DBC layout of an identifier, or None if the id is not in the protocol."""
    return _BY_ID.get(arbitration_id)


def decode_frame(frame: Frame) -> tuple[str, dict[str, int | float]]:
    """Strictly decode one frame into (DBC message name, physical signal values).

    Raises DecodeError naming the message/field: unknown id, wrong length, impossible value."""
    lay = _BY_ID.get(frame.arbitration_id)
    if lay is None:
        raise DecodeError(f"frame id 0x{frame.arbitration_id:03X} is not in the protocol")
    if len(frame.data) != lay.length:
        raise DecodeError(f"{lay.name}: {len(frame.data)} data bytes, expected {lay.length}")
    raw = lay.unpack(bytes(frame.data))
    out: dict[str, int | float] = {}
    for sig, r in zip(lay.signals, raw, strict=True):
        if sig.scale == 1.0 and sig.offset == 0.0:
            out[sig.name] = r
        else:
            out[sig.name] = r * sig.scale + sig.offset
    if "n_states" in out and not 1 <= int(out["n_states"]) <= MAX_STATES:
        raise DecodeError(f"{lay.name}.n_states={out['n_states']} out of range (1..{MAX_STATES})")
    if "n_duties" in out and int(out["n_duties"]) not in codec_duty.N_DUTIES:
        raise DecodeError(f"{lay.name}.n_duties={out['n_duties']} out of range (3 or 6)")
    return lay.name, out


def decode_message(frames: Iterable[Frame]) -> Message:
    """Strictly decode the frames of exactly one message (all parts, same seq).

    Raises DecodeError naming the message/field if a frame is bad or the parts do not assemble."""
    dec = FrameDecoder()
    result: Message | None = None
    for fr in frames:
        name, _ = decode_frame(fr)  # raises with the field named
        msg = dec.feed(fr)
        if msg is not None:
            if result is not None:
                raise DecodeError(f"{name}: frames contain more than one message")
            result = msg
    if result is None:
        s = dec.stats
        raise DecodeError(
            f"frames do not form a complete message (mixed_seq={s.mixed_seq}, duplicate={s.duplicate}, stale={s.stale})"
        )
    return result
