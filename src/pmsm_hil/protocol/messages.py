"""Logical messages exchanged between host (plant, node 0) and target (controller, node 1).

Physical units: currents A, angle rad (electrical), speed rad/s (mechanical), voltage V,
durations and execution time ns. The frame layouts live in `hil.dbc`; see docs/protocol.md.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True, slots=True)
class Measurement:
    """Plant -> target sample k: phase currents [A], electrical angle [rad], mechanical speed [rad/s],
    DC-link voltage [V]. `seq` wraps at 65536; `theta_e` wraps into [0, 2π)."""

    seq: int
    i_a: float
    i_b: float
    i_c: float
    theta_e: float
    omega_m: float
    vdc: float
    status: int = 0


@dataclass(frozen=True, slots=True)
class Measurement6:
    """Plant -> target sample k of a dual three-phase machine: currents of set 1 (i_a, i_b, i_c) and set 2
    (i_u, i_v, i_w) [A] (frames: int16 × 0.01 A, ±327.67 A), electrical angle [rad], mechanical speed
    [rad/s], DC-link voltage [V]. Same wrapping and saturation rules as `Measurement`."""

    seq: int
    i_a: float
    i_b: float
    i_c: float
    i_u: float
    i_v: float
    i_w: float
    theta_e: float
    omega_m: float
    vdc: float
    status: int = 0


@dataclass(frozen=True, slots=True)
class Command:
    """Target -> plant switching sequence for the period after next.

    `states[j]` (6-bit switching state code) is applied for `durations_ns[j]` ns; the durations sum
    to Ts. With `mirror` the plant applies states[0..n-1] then states[n-2..0], the mirrored copies with
    the same durations, so 2·(d0 + … + d(n-2)) + d(n-1) = Ts (a symmetric sequence of 2n − 1 intervals,
    see `expanded`). `seq` echoes the measurement's; `exec_time_ns` is clamped to 2^32 - 1 on encode.

    Duty-cycle form: `duties` holds 3 or 6 per-leg duties 0..1 of a centre-aligned PWM whose carrier period is
    Ts (legs a, b, c, then u, v, w) and `states`/`durations_ns` are empty, `mirror` False; the plant applies
    the carrier comparison (`pmsm_hil.hil.pwm`). A duty outside 0..1 or NaN is sent as a reserved code and
    decoded as +inf / NaN: a DUT-contract finding at the host. A Command that sets both forms (duties and a
    switching sequence) is sent as a duty Command with `n_duties` 0 and decodes with `both_forms` set: a
    DUT-contract finding too (the target core reports its firmware's so)."""

    seq: int
    states: tuple[int, ...]
    durations_ns: tuple[int, ...]
    vector_id: int = 0
    candidates: int = 0
    exec_time_ns: int = 0
    status: int = 0
    mirror: bool = False
    duties: tuple[float, ...] = ()
    #: decoded: the sender's Command set both forms (a duty Command with n_duties 0 on the wire)
    both_forms: bool = False

    def expanded(self) -> tuple[tuple[int, ...], tuple[int, ...]]:
        """(states, durations_ns) as the plant applies them: unchanged, or mirrored when `mirror`."""
        return expand_mirror(self.states, self.durations_ns, self.mirror)


def expand_mirror(
    states: tuple[int, ...], durations_ns: tuple[int, ...], mirror: bool
) -> tuple[tuple[int, ...], tuple[int, ...]]:
    """The applied sequence of a command: s0..s(n-1) then s(n-2)..s0 (same durations) if `mirror`."""
    if not mirror or len(states) < 2:
        return states, durations_ns
    return states + states[-2::-1], durations_ns + durations_ns[-2::-1]


@dataclass(frozen=True, slots=True)
class Setpoint:
    """Host -> target: enable, mode (0 speed [rad/s mechanical], 1 torque [N·m]), reference (float32)
    and the controller to run (`ControllerId`)."""

    enable: bool
    mode: int
    reference: float
    controller_id: int


@dataclass(frozen=True, slots=True)
class ConfigParam:
    """Host -> target parameter write; `value` float32 in SI units (see `ParamId`)."""

    param_id: int
    value: float


@dataclass(frozen=True, slots=True)
class ConfigAck:
    """Target -> host acknowledge of a ConfigParam: value echoed, status 0 ok or 5 invalid."""

    param_id: int
    value: float
    status: int


@dataclass(frozen=True, slots=True)
class Heartbeat:
    """Liveness frame, both ways; `node` 0 host, 1 target; `state` a `NodeState`; `counter` wraps at 256."""

    node: int
    state: int
    counter: int


@dataclass(frozen=True, slots=True)
class Fault:
    """Fault report, both ways; `code` a `Status` code, `detail` free u32 (e.g. offending id)."""

    node: int
    code: int
    detail: int = 0


Message = Measurement | Measurement6 | Command | Setpoint | ConfigParam | ConfigAck | Heartbeat | Fault

MESSAGE_TYPES: tuple[type, ...] = (
    Measurement, Measurement6, Command, Setpoint, ConfigParam, ConfigAck, Heartbeat, Fault,
)
