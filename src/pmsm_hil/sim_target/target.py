"""The virtual target: runs the C reference firmware behind any link, speaking the frame protocol."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from pmsm_hil.protocol import Command, ConfigAck, ConfigParam, Fault, Heartbeat, Measurement, Measurement6, Setpoint
from pmsm_hil.protocol.codec import MAX_DURATION_NS, FrameCodec
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.ids import ControllerId, NodeState, ParamId, Status
from pmsm_hil.protocol.links import Link
from pmsm_hil.sim_target.firmware import Firmware, FirmwareCommand, FirmwareConfigError

TARGET_NODE = 1
_IDLE_STATE = 0  # zero vector (all lower switches on) while disabled


def serve_pending(poll: Callable[[], Frame | None], handle: Callable[[Frame], None]) -> int:
    """Hand every frame waiting on a link (`poll` until it returns None) to `handle`; returns how many there were."""
    handled = 0
    while True:
        frame = poll()
        if frame is None:
            return handled
        handled += 1
        handle(frame)


@dataclass(slots=True)
class TargetCounters:
    """What the target saw: measurements, commands sent, config writes, faults raised."""

    measurements: int = 0
    commands: int = 0
    config_writes: int = 0
    config_rejected: int = 0
    faults: int = 0


class SimTarget:
    """Firmware stub + protocol endpoint. Call `service()` to process every pending frame (non-blocking).

    Time for the control law is the measurement count times the configured Ts (virtual time), so
    lockstep runs are bit-identical; the controller's execution time is measured around the C step.
    """

    def __init__(self, link: Link, codec: FrameCodec, *, silent_after: int | None = None) -> None:
        self.link = link
        self.codec = codec
        self.decoder = codec.decoder()
        self.firmware = Firmware()
        self.counters = TargetCounters()
        self.enabled = False
        self.controller_id = int(ControllerId.OFF)
        self.ts_ns = 100_000
        self.last_result: FirmwareCommand | None = None
        self._silent_after = silent_after
        self._k = 0
        self._beats = 0  # HeartbeatTarget frames sent on its own (the counter of the next one, mod 256)

    def service(self) -> int:
        """Process all frames waiting on the link; returns the number of frames handled."""
        return serve_pending(self.link.poll, self._on_frame)

    def _on_frame(self, frame: Frame) -> None:
        msg = self.decoder.feed(frame)
        if msg is not None:
            self._dispatch(msg)

    def _dispatch(self, msg: object) -> None:
        if isinstance(msg, Measurement):
            self._on_measurement(msg, (msg.i_a, msg.i_b, msg.i_c))
        elif isinstance(msg, Measurement6):
            self._on_measurement(msg, (msg.i_a, msg.i_b, msg.i_c, msg.i_u, msg.i_v, msg.i_w))
        elif isinstance(msg, ConfigParam):
            self._on_config(msg)
        elif isinstance(msg, Setpoint):
            self._on_setpoint(msg)
        elif isinstance(msg, Heartbeat) and msg.node != TARGET_NODE:
            state = NodeState.RUNNING if self.enabled else NodeState.IDLE
            self._send(Heartbeat(node=TARGET_NODE, state=int(state), counter=msg.counter))

    def _send(self, msg: Command | ConfigAck | Fault | Heartbeat) -> None:
        self.link.send(self.codec.encode(msg))

    def _on_measurement(self, m: Measurement | Measurement6, currents: tuple[float, ...]) -> None:
        self.counters.measurements += 1
        if self._silent_after is not None and self.counters.measurements > self._silent_after:
            return  # fault injection: a target that stopped answering
        t_ns = self._k * self.ts_ns
        self._k += 1
        if not self.enabled:
            cmd = Command(seq=m.seq, states=(_IDLE_STATE,), durations_ns=(self.ts_ns,))
        else:
            res = self.firmware.step(m.seq, currents, m.theta_e, m.omega_m, m.vdc, t_ns)
            self.last_result = res
            cmd = Command(seq=m.seq, states=res.states, durations_ns=res.durations_ns, vector_id=res.vector_id,
                          candidates=res.candidates, exec_time_ns=min(res.exec_time_ns, 0xFFFFFFFF),
                          status=res.status, mirror=res.mirror, duties=res.duties)
        self.counters.commands += 1
        self._send(cmd)

    def _on_config(self, c: ConfigParam) -> None:
        # a host configures before every run: the next run numbers its Measurements from 0 again, which the
        # decoder's ordering would otherwise drop as stale after a short earlier run
        self.decoder.restart()
        self.counters.config_writes += 1
        is_ts = c.param_id == int(ParamId.TS)
        try:
            if is_ts and not c.value * 1e9 < MAX_DURATION_NS + 0.5:  # NaN fails too
                raise FirmwareConfigError(f"ts: {c.value!r} s is longer than a Command can carry "
                                          f"({MAX_DURATION_NS} ns)")
            self.firmware.set_param(c.param_id, c.value)
            status = int(Status.OK)
            if is_ts:
                self.ts_ns = round(c.value * 1e9)
        except FirmwareConfigError:
            self.counters.config_rejected += 1
            status = int(Status.INVALID_CONFIG)
        self._send(ConfigAck(param_id=c.param_id, value=c.value, status=status))

    def _on_setpoint(self, s: Setpoint) -> None:
        self._apply_setpoint(s)
        if not s.enable:  # the confirmed safe stop: disabled now, and says so
            self._send(Heartbeat(node=TARGET_NODE, state=int(NodeState.IDLE), counter=self._beats & 0xFF))
            self._beats += 1

    def _apply_setpoint(self, s: Setpoint) -> None:
        if s.controller_id != self.controller_id:
            try:
                self.firmware.select_controller(s.controller_id)
            except FirmwareConfigError:
                self._refuse(Status.NOT_IMPLEMENTED, s.controller_id)
                return
            self.controller_id = s.controller_id
        try:
            self.firmware.set_setpoint(s.enable, s.mode, s.reference)
        except FirmwareConfigError:
            self._refuse(Status.INVALID_CONFIG, s.mode)
            return
        self.enabled = s.enable

    def _refuse(self, code: Status, detail: int) -> None:
        """A Setpoint the firmware refused: disabled, a Fault with `code` and `detail` sent and counted."""
        self.counters.faults += 1
        self.enabled = False
        self._send(Fault(node=TARGET_NODE, code=int(code), detail=detail))

    def run_forever(self, should_stop: Callable[[], bool], idle_sleep_s: float = 0.0, block_s: float = 0.0) -> None:
        """Poll the link until should_stop() is true (checked every ~1000 empty polls); after each check a sleep of
        `idle_sleep_s` [s], and (`block_s` > 0) a wait of up to `block_s` [s] in the link's receive (blocked on the
        wire buses): a target idle between runs leaves the CPU to others, and polls again from its next frame on."""
        spins = 0
        recv = self.link.recv if block_s > 0 else None
        while True:
            if self.service():
                spins = 0
                continue
            spins += 1
            if spins >= 1000:
                spins = 0
                if should_stop():
                    return
                if idle_sleep_s:
                    time.sleep(idle_sleep_s)
                if recv is not None:
                    frame = recv(block_s)
                    if frame is not None:
                        self._on_frame(frame)
                    else:  # still idle: the next empty poll checks and waits again
                        spins = 999
