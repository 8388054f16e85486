"""A foreign target for the conformance suite: the control law of examples/python_target.py (written from
docs/protocol.md alone) plus the FaultTarget for an undefined Setpoint mode, which breaks one rule on request.

Usage: python conformance_target.py LINKSPEC [--break RULE]
Rules it can break: durations (the 30th Measurement answered with durations 1 ns short of Ts), safe_stop
(a disabling Setpoint is never answered with HeartbeatTarget idle).
"""

from __future__ import annotations

import argparse
import dataclasses
import runpy
from pathlib import Path
from typing import Any

from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.ids import Mode, Status
from pmsm_hil.protocol.links import open_link
from pmsm_hil.protocol.messages import Command, Fault, Heartbeat, Measurement, Message, Setpoint

EXAMPLE = runpy.run_path(str(Path(__file__).resolve().parents[2] / "examples" / "python_target.py"))
BREAKS = ("durations", "safe_stop")


class ConformanceTarget(EXAMPLE["ExampleTarget"]):  # type: ignore[misc]
    """ExampleTarget + the undefined-mode fault; `breaks`: the rule it breaks (None: none)."""

    def __init__(self, breaks: str | None = None) -> None:
        super().__init__()
        self.breaks = breaks
        self.measurements = 0

    def on_setpoint(self, msg: Setpoint) -> list[Any]:
        if msg.mode not in (Mode.SPEED, Mode.TORQUE):
            self.setpoint = None
            return [Fault(node=EXAMPLE["TARGET_NODE"], code=int(Status.INVALID_CONFIG), detail=msg.mode)]
        replies: list[Any] = super().on_setpoint(msg)
        return replies

    def handle(self, msg: Message) -> list[Any]:
        replies: list[Any] = super().handle(msg)
        if self.breaks == "safe_stop":  # disables, but never confirms it
            replies = [r for r in replies if not isinstance(r, Heartbeat)]
        if isinstance(msg, Measurement):
            self.measurements += 1
            if self.breaks == "durations" and self.measurements == 30:
                replies = [dataclasses.replace(r, durations_ns=(r.durations_ns[0] - 1, *r.durations_ns[1:]))
                           if isinstance(r, Command) else r for r in replies]
        return replies


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("link", help="link spec, e.g. udp:47311:47310 or serial:fd:5")
    parser.add_argument("--break", dest="breaks", choices=BREAKS, help="the rule to break")
    args = parser.parse_args()
    target = ConformanceTarget(args.breaks)
    with open_link(args.link, role="target") as link:
        codec = FrameCodec("canfd" if link.fd else "can")
        decoder = codec.decoder()
        print("ready", flush=True)
        while True:  # until terminated
            frame = link.recv(timeout_s=1.0)
            msg = decoder.feed(frame) if frame is not None else None
            for reply in target.handle(msg) if msg is not None else []:
                link.send(codec.encode(reply))


if __name__ == "__main__":
    main()
