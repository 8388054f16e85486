"""A foreign controller target in Python, written from docs/protocol.md alone: the protocol's codec
(`pmsm_hil.protocol.codec.FrameCodec`, `pmsm_hil.protocol.messages`) over any link, no reference firmware.

It answers as a board would: every ConfigParam with a ConfigAck echoing the value (status 5 for NaN or ±inf),
every Measurement with a Command echoing its seq (a full-period zero vector while disabled), every disabling
Setpoint with a HeartbeatTarget in state idle (the confirmed safe stop), and a Fault for a controller id it does
not implement. Its control law uses only the documented conventions (θe = 0 with the d axis on phase a,
positive speed turns a→b→c, amplitude-invariant Clarke, state code 4·Sa + 2·Sb + Sc with
S = 1 the upper switch on) and ConfigParam values: the speed PI of docs/algorithms/speed_pi.md (parallel form,
forward rectangle, clamped integrator) feeding a one-step finite-control-set current controller in the stator
frame (i_d = 0; it predicts over the period in flight, then picks the best of the 8 states). Three phases
only.

Run (two shells):   python examples/python_target.py --link udp:47311:47310
                    hil run --link udp --target external --controller external
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable

from pmsm_hil.protocol import Command, ConfigAck, ConfigParam, Fault, Heartbeat, Measurement, Measurement6, Setpoint
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.ids import ControllerId, Mode, NodeState, ParamId, Status
from pmsm_hil.protocol.links import Link, open_link
from pmsm_hil.protocol.messages import Message

TARGET_NODE = 1
#: (v_alpha, v_beta) per volt of Vdc of state code 4·Sa + 2·Sb + Sc (amplitude-invariant Clarke)
VOLTS = [((2 * (c >> 2 & 1) - (c >> 1 & 1) - (c & 1)) / 3.0, ((c >> 1 & 1) - (c & 1)) / math.sqrt(3.0))
         for c in range(8)]


def _clamp(x: float, limit: float) -> float:
    return max(-limit, min(limit, x))


class ExampleTarget:
    """The protocol endpoint and its control law; `handle` maps one received message to the replies."""

    def __init__(self) -> None:
        self.params: dict[int, float] = {int(ParamId.TS): 100e-6}
        self.setpoint: Setpoint | None = None
        self.integ = 0.0  # speed PI integrator [N·m]
        self.last_state = 0  # state code of the command in flight (applied during the current period)
        self.beats = 0  # HeartbeatTarget frames sent (the counter of the next one, mod 256)

    def p(self, pid: ParamId, default: float = 0.0) -> float:
        """A ConfigParam value (SI units), or `default` before it was written."""
        return self.params.get(int(pid), default)

    def handle(self, msg: Message) -> list[Message]:
        """Replies to one message (empty for messages that need none)."""
        if isinstance(msg, ConfigParam):
            if not math.isfinite(msg.value):  # a frame can carry NaN or ±inf: refused, the value still echoed
                return [ConfigAck(param_id=msg.param_id, value=msg.value, status=int(Status.INVALID_CONFIG))]
            self.params[msg.param_id] = msg.value
            return [ConfigAck(param_id=msg.param_id, value=msg.value, status=int(Status.OK))]
        if isinstance(msg, Setpoint):
            replies = self.on_setpoint(msg)
            if not msg.enable:  # the confirmed safe stop: disabled now, and says so
                replies.append(Heartbeat(node=TARGET_NODE, state=int(NodeState.IDLE), counter=self.beats & 0xFF))
                self.beats += 1
            return replies
        if isinstance(msg, Measurement6):
            return [Fault(node=TARGET_NODE, code=int(Status.INVALID_CONFIG), detail=6)]  # three phases only
        if isinstance(msg, Measurement):
            ts_ns = round(self.p(ParamId.TS) * 1e9)
            sp = self.setpoint
            state = self.control(msg, sp) if sp is not None and sp.enable and sp.controller_id else 0
            self.last_state = state
            return [Command(seq=msg.seq, states=(state,), durations_ns=(ts_ns,), candidates=8 if state else 0)]
        return []

    def on_setpoint(self, msg: Setpoint) -> list[Message]:
        """Take a Setpoint: a Fault for a controller id this target lacks (and disabled)."""
        if msg.controller_id not in (ControllerId.OFF, ControllerId.EXTERNAL):
            self.setpoint = None
            return [Fault(node=TARGET_NODE, code=int(Status.NOT_IMPLEMENTED), detail=msg.controller_id)]
        rising = msg.enable and not (self.setpoint is not None and self.setpoint.enable)
        if rising and msg.mode == Mode.SPEED:  # bumpless start: preset the integrator
            self.integ = _clamp(self.p(ParamId.TORQUE_INTEGRATOR_INIT), self.p(ParamId.TORQUE_LIMIT))
        self.setpoint = msg
        return []

    def control(self, m: Measurement, sp: Setpoint) -> int:
        """State code for the period after next: speed PI -> i_q reference -> best of the 8 states."""
        ts, rs, psi = self.p(ParamId.TS), self.p(ParamId.RS), self.p(ParamId.PSI_F)
        pp, limit = self.p(ParamId.POLE_PAIRS, 1.0), self.p(ParamId.TORQUE_LIMIT)
        ls = 0.5 * (self.p(ParamId.LD) + self.p(ParamId.LQ))
        vdc = m.vdc if m.vdc > 0 else self.p(ParamId.VDC)
        if sp.mode == Mode.SPEED:  # parallel PI, continuous-time gains, forward rectangle, clamped integrator
            err = sp.reference - m.omega_m
            self.integ = _clamp(self.integ + self.p(ParamId.SPEED_KI) * err * ts, limit)
            torque = _clamp(self.p(ParamId.SPEED_KP) * err + self.integ, limit)
        else:
            torque = _clamp(sp.reference, limit)
        iq_ref = torque / (1.5 * pp * psi)
        we = pp * m.omega_m

        def predict(i_al: float, i_be: float, theta: float, code: int) -> tuple[float, float]:
            va, vb = VOLTS[code]  # back-EMF ω_e ψ_f (−sin θ, cos θ): the d axis is at θ in the stator frame
            return (i_al + ts / ls * (va * vdc - rs * i_al + we * psi * math.sin(theta)),
                    i_be + ts / ls * (vb * vdc - rs * i_be - we * psi * math.cos(theta)))

        i_al, i_be = (2 * m.i_a - m.i_b - m.i_c) / 3.0, (m.i_b - m.i_c) / math.sqrt(3.0)
        i1 = predict(i_al, i_be, m.theta_e, self.last_state)  # the command in flight, to the next period start
        th2 = m.theta_e + 2.0 * we * ts
        ref = (-iq_ref * math.sin(th2), iq_ref * math.cos(th2))  # (i_d, i_q) = (0, iq_ref) at k + 2

        def cost(code: int) -> float:
            a, b = predict(*i1, m.theta_e + we * ts, code)
            return (a - ref[0]) ** 2 + (b - ref[1]) ** 2

        return min(range(8), key=cost)


def serve(link: Link, should_stop: Callable[[], bool] = lambda: False) -> ExampleTarget:
    """Answer the host on `link` until should_stop() (checked after each quiet second) is true."""
    target, codec = ExampleTarget(), FrameCodec("canfd" if link.fd else "can")
    decoder = codec.decoder()  # accepts both profiles; reassembles the classic parts by seq
    while not should_stop():
        frame = link.recv(timeout_s=1.0)
        msg = decoder.feed(frame) if frame is not None else None
        for reply in target.handle(msg) if msg is not None else []:
            link.send(codec.encode(reply))
    return target


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--link", default="udp:47311:47310", help="link spec (docs/protocol.md); default %(default)s")
    with open_link(parser.parse_args().link, role="target") as lk:
        serve(lk)
