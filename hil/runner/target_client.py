"""Host side of the frame protocol: configures the target and exchanges measurement/command frames."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping

from pmsm_hil.hil.errors import HilError
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.ids import ParamId, Status
from pmsm_hil.protocol.links import Link
from pmsm_hil.protocol.messages import Command, ConfigAck, ConfigParam, Fault, Measurement, Measurement6, Setpoint


class TargetError(HilError):
    """The target rejected a configuration, reported a fault or did not answer."""


class TargetClient:
    """Talks to one target over a link. ``pump`` (in-process target) is called while waiting."""

    def __init__(self, link: Link, codec: FrameCodec, pump: Callable[[], object] | None = None) -> None:
        self.link = link
        self.codec = codec
        self.decoder = codec.decoder()
        self.pump = pump
        self.faults: list[Fault] = []
        self.stale_commands = 0
        self._acks: dict[int, ConfigAck] = {}
        self._commands: dict[int, Command] = {}

    def _drain(self) -> None:
        if self.pump is not None:
            self.pump()
        poll, feed = self.link.poll, self.decoder.feed
        while True:
            frame = poll()
            if frame is None:
                return
            msg = feed(frame)
            if msg is None:
                continue
            if isinstance(msg, Command):
                self._commands[msg.seq] = msg
            elif isinstance(msg, ConfigAck):
                self._acks[msg.param_id] = msg
            elif isinstance(msg, Fault):
                self.faults.append(msg)

    def configure(self, params: Mapping[ParamId, float], timeout_s: float = 10.0,
                  resend_s: float = 0.25) -> None:
        """Write every parameter until acknowledged (resending every resend_s, so a target that is
        still starting up is caught); raises naming a rejected or unacknowledged parameter."""
        self._acks.clear()
        start = time.perf_counter()
        last_send = -math.inf
        while True:
            now = time.perf_counter()
            pending = [p for p in params if int(p) not in self._acks]
            if not pending:
                break
            if now - start > timeout_s:
                missing = ", ".join(ParamId(p).name.lower() for p in pending)
                raise TargetError(f"target did not acknowledge parameter(s) {missing} within {timeout_s} s "
                                  "(is a target running on this link?)")
            if now - last_send >= resend_s:
                for pid in pending:
                    self.link.send(self.codec.encode(ConfigParam(param_id=int(pid), value=float(params[pid]))))
                last_send = now
            self._drain()
        for pid in params:
            ack = self._acks[int(pid)]
            if ack.status != int(Status.OK):
                raise TargetError(f"target rejected parameter '{ParamId(pid).name.lower()}' = {params[pid]}")

    def set_setpoint(self, *, enable: bool, mode: int, reference: float, controller_id: int) -> None:
        """Send a setpoint (enable, mode, reference in rad/s or N·m, controller id)."""
        self.link.send(self.codec.encode(Setpoint(enable=enable, mode=mode, reference=reference,
                                                  controller_id=controller_id)))

    def check_faults(self) -> None:
        """Raise if the target reported a fault."""
        self._drain()
        if self.faults:
            f = self.faults[0]
            name = Status(f.code).name.lower() if f.code in Status._value2member_map_ else str(f.code)
            raise TargetError(f"target fault: {name} (detail {f.detail})")

    def send_measurement(self, m: Measurement | Measurement6) -> None:
        """Send one measurement (one or two frames depending on the profile)."""
        self.link.send(self.codec.encode(m))

    def poll_command(self, seq: int) -> Command | None:
        """Non-blocking: the command answering measurement ``seq`` if it has arrived."""
        self._drain()
        cmd = self._commands.pop(seq, None)
        if self._commands:
            self.stale_commands += len(self._commands)  # answers to older measurements arriving late
            self._commands.clear()
        return cmd
