"""A foreign controller target in Python that ends, as drive firmware does, in three duty cycles of a
centre-aligned PWM (`Command.duties`, docs/protocol.md "Duty-cycle Command"): the protocol endpoint of
examples/python_target.py (ConfigAck, safe stop, Faults) with field-oriented control in place of its
finite-control-set law: the same speed PI, then d/q current PI loops (i_d = 0, bandwidth 2π·1 kHz from the
ConfigParam inductances and resistance, back-EMF and cross-coupling feed-forward), the voltage rotated to the
middle of the period it is applied in, and space-vector PWM as min-max zero-sequence injection:
d_x = 1/2 + (v_x − (max v + min v)/2) / Vdc. The host's plant compares the duties with its carrier (all 7
segments 0-x-xy-7-xy-x-0). Three phases only.

Run (two shells):   python examples/python_duty_target.py --link udp:47311:47310
                    hil run --link udp --target external --controller external
"""

from __future__ import annotations

import argparse
import math
import runpy
from pathlib import Path
from typing import Any

from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.ids import Mode, ParamId
from pmsm_hil.protocol.links import Link, open_link
from pmsm_hil.protocol.messages import Command, Measurement, Message, Setpoint

_BASE: Any = runpy.run_path(str(Path(__file__).with_name("python_target.py")))
BANDWIDTH_RAD_S = 2.0 * math.pi * 1000.0
SQRT3 = math.sqrt(3.0)


def svpwm_duties(v_alpha: float, v_beta: float, vdc: float) -> tuple[float, float, float]:
    """Duties 0..1 of legs a, b, c for a stator-frame voltage [V] (scaled onto the hexagon's circle)."""
    mag = math.hypot(v_alpha, v_beta)
    k = min(1.0, vdc / SQRT3 / mag) if mag > 0.0 else 1.0
    v = (k * v_alpha, k * (-0.5 * v_alpha + 0.5 * SQRT3 * v_beta), k * (-0.5 * v_alpha - 0.5 * SQRT3 * v_beta))
    mid = 0.5 * (max(v) + min(v))
    return tuple(min(1.0, max(0.0, 0.5 + (x - mid) / vdc)) for x in v)  # type: ignore[return-value]


class DutyTarget(_BASE["ExampleTarget"]):  # type: ignore[misc]
    """ExampleTarget with FOC ending in duty cycles."""

    def __init__(self) -> None:
        super().__init__()
        self.x_d = self.x_q = 0.0  # current PI integrators [V]

    def handle(self, msg: Message) -> list[Message]:
        """As ExampleTarget, but an enabled Measurement gets a duty-cycle Command."""
        sp = self.setpoint
        if isinstance(msg, Measurement) and sp is not None and sp.enable and sp.controller_id:
            return [Command(seq=msg.seq, states=(), durations_ns=(), duties=self.foc(msg, sp))]
        if isinstance(msg, Setpoint) and msg.enable and not (sp is not None and sp.enable):
            self.x_d = self.x_q = 0.0
        return list(super().handle(msg))

    def foc(self, m: Measurement, sp: Setpoint) -> tuple[float, ...]:
        """Duties for the period after next: speed PI → i_q reference → d/q PI → SVPWM."""
        p = self.p
        ts, rs, psi, ld, lq = p(ParamId.TS), p(ParamId.RS), p(ParamId.PSI_F), p(ParamId.LD), p(ParamId.LQ)
        pp, limit = p(ParamId.POLE_PAIRS, 1.0), p(ParamId.TORQUE_LIMIT)
        vdc = m.vdc if m.vdc > 0 else p(ParamId.VDC)
        if sp.mode == Mode.SPEED:
            err = sp.reference - m.omega_m
            self.integ = max(-limit, min(limit, self.integ + p(ParamId.SPEED_KI) * err * ts))
            torque = max(-limit, min(limit, p(ParamId.SPEED_KP) * err + self.integ))
        else:
            torque = max(-limit, min(limit, sp.reference))
        iq_ref = torque / (1.5 * pp * psi)
        c, s = math.cos(m.theta_e), math.sin(m.theta_e)
        i_al, i_be = (2 * m.i_a - m.i_b - m.i_c) / 3.0, (m.i_b - m.i_c) / SQRT3
        i_d, i_q = i_al * c + i_be * s, -i_al * s + i_be * c
        we = pp * m.omega_m
        vmax = vdc / SQRT3
        e_d, e_q = -i_d, iq_ref - i_q
        v_d = BANDWIDTH_RAD_S * ld * e_d + self.x_d - we * lq * i_q
        v_q = BANDWIDTH_RAD_S * lq * e_q + self.x_q + we * (ld * i_d + psi)
        if math.hypot(v_d, v_q) <= vmax:  # conditional integration: no wind-up in saturation
            self.x_d += BANDWIDTH_RAD_S * rs * ts * e_d
            self.x_q += BANDWIDTH_RAD_S * rs * ts * e_q
        th = m.theta_e + 1.5 * we * ts  # applied over [k+1, k+2): its middle
        c, s = math.cos(th), math.sin(th)
        return svpwm_duties(v_d * c - v_q * s, v_d * s + v_q * c, vdc)


def serve(link: Link) -> DutyTarget:
    """Answer the host on `link` until interrupted."""
    target, codec = DutyTarget(), FrameCodec("canfd" if link.fd else "can")
    decoder = codec.decoder()
    while True:
        frame = link.recv(timeout_s=1.0)
        msg = decoder.feed(frame) if frame is not None else None
        for reply in target.handle(msg) if msg is not None else []:
            link.send(codec.encode(reply))


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--link", default="udp:47311:47310", help="link spec (docs/protocol.md); default %(default)s")
    with open_link(parser.parse_args().link, role="target") as lk:
        serve(lk)
