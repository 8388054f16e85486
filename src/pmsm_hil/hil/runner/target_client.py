"""Host side of the frame protocol: configures the target and exchanges measurement/command frames."""

from __future__ import annotations

import math
import struct
import time
from collections import deque
from collections.abc import Callable, Mapping
from typing import Any

from pmsm_hil.hil.errors import HilError
from pmsm_hil.hil.runner.contract import FRAME, SEQUENCE, describe
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.ids import ParamId, Status
from pmsm_hil.protocol.links import Link
from pmsm_hil.protocol.links.shared_bus import (
    BusTraffic,
    bus_starved_reason,
    command_ids,
    command_seq,
    fault_target_id,
    target_lengths,
)
from pmsm_hil.protocol.links.wire_core import link_end
from pmsm_hil.protocol.messages import (
    Command,
    ConfigAck,
    ConfigParam,
    Fault,
    Heartbeat,
    Measurement,
    Measurement6,
    Setpoint,
)
from pmsm_hil.sim_target.fw_params import FirmwareParamId

_F32 = struct.Struct("<f")
#: node id of the target (`Node` in the DBC)
TARGET_NODE = 1
#: frames one drain takes at most: a bus flooded by other nodes never empties, and the caller's deadline must
#: still be checked (the C loop's NL_DRAIN_MAX, src/pmsm_hil/hil/runner/c/links/nl_link.h)
DRAIN_MAX = 256
#: links wrapped around the target's own at most (the frame recorder, the callback link, a fault injector)
WRAPPERS_MAX = 3



def _param_name(pid: int) -> str:
    """A parameter's name: a ParamId member's, a firmware-declared one's
    (`pmsm_hil.sim_target.fw_params.FirmwareParamId` carries it), else `param_ID`."""
    name = getattr(pid, "name", None)
    if name is None and pid in ParamId._value2member_map_:
        name = ParamId(pid).name
    return str(name).lower() if name is not None else f"param_{int(pid)}"

class TargetError(HilError):
    """The target rejected a configuration, reported a fault or did not answer."""


class DutViolationError(TargetError):
    """The target broke the contract while being configured (no ConfigAck, or an echo of another value)."""


class HostStallError(HilError):
    """Lockstep: the host kept the target's process stopped or off the CPUs longer than `--host-stall-limit`
    while the run waited for a Command (the host's fault, not the firmware's: exit 1)."""


class BusStarvedError(HilError):
    """Other nodes' frames on a shared bus kept the target's answers out (the message names the bus); not the
    target's fault."""


class TargetClient:
    """Talks to one target over a link. ``pump`` (in-process target) is called while waiting."""

    def __init__(self, link: Link, codec: FrameCodec, pump: Callable[[], object] | None = None,
                 shared: bool | None = None) -> None:
        self.link = link
        #: other nodes may share the bus (src/pmsm_hil/protocol/links/shared_bus.py; default: the link's own `shared`):
        #: frames that cannot be the target's are counted in `bus`, never taken as its or as findings
        self.shared: bool = bool(getattr(link, "shared", False)) if shared is None else shared
        self.bus = BusTraffic()
        #: the last drain stopped at DRAIN_MAX frames with the queue not seen empty (a flood outpacing the host)
        self.backlog = False
        #: the link's name in an ending the bus caused ("bus socketcan:vcan0: …")
        self.bus_name: str = str(getattr(link, "description", "") or "the link")
        self._target_lengths, self._command_ids, self._fault_id = target_lengths(), command_ids(), fault_target_id()
        self._written: dict[int, float] = {}  # parameters being configured: the float32 written
        self._controller_id: int | None = None  # of the last Setpoint sent
        self._mode: int | None = None  # of the last Setpoint sent
        self.codec = codec
        self.decoder = codec.decoder(ordered=False)  # the contract checks each Command's seq itself
        self.pump = pump
        self.faults: list[Fault] = []
        #: the last HeartbeatTarget frames received (the safe stop's confirmation, src/pmsm_hil/hil/runner/safe_stop.py)
        self.heartbeats: deque[Heartbeat] = deque(maxlen=16)
        #: frames received from the target so far (any kind)
        self.frames_in = 0
        #: replies to the previous period that arrived after it was declared missing (late; not a new finding)
        self.stale_commands = 0
        #: ConfigParam frames sent again for want of a ConfigAck within `configure`'s resend_s (wall time: a
        #: target still starting or slow to answer), and ConfigAcks for a parameter acknowledged already (the
        #: target's answer to such a resend). Counted apart so the link counters can be compared between runs.
        self.config_resent = 0
        self.config_acks_repeated = 0
        #: contract findings since the last `take_anomalies()`: (rule, frame text, detail)
        self.anomalies: list[tuple[str, str, str]] = []
        self._acks: dict[int, ConfigAck] = {}
        self._expected = -1  # seq of the last Measurement sent
        self._reply: Command | None = None  # the genuine reply to it
        self._prev_answered = True  # did the period before get its reply?
        self._malformed = 0  # decoder rejects seen so far: bad length/value
        self._out_of_seq = 0  # and old/repeated seq parts

    def _drain(self, first: Frame | None = None) -> None:
        """Take every frame waiting on the link (`first`: one received already, taken before them)."""
        if self.pump is not None:
            self.pump()
        poll, feed, shared = self.link.poll, self.decoder.feed, self.shared
        self.backlog = True  # until the queue is seen empty
        frame: Frame | None
        for _ in range(DRAIN_MAX):
            if first is not None:
                frame, first = first, None
            else:
                frame = poll()
            if frame is None:
                self.backlog = False
                return
            self.frames_in += 1
            if shared and not self._from_target(frame):
                continue
            msg = feed(frame)
            if msg is None:
                continue
            if isinstance(msg, Command):
                self._on_command(msg)
            elif isinstance(msg, ConfigAck):
                if shared and not self._ack_plausible(msg):
                    self.bus.suspect += 1
                    continue
                if msg.param_id in self._acks:
                    self.config_acks_repeated += 1
                self._acks[msg.param_id] = msg
            elif isinstance(msg, Fault):
                self.faults.append(msg)
            elif isinstance(msg, Heartbeat) and msg.node == TARGET_NODE:
                self.heartbeats.append(msg)

    def _from_target(self, frame: Frame) -> bool:
        """A shared bus: can `frame` be the target's? (src/pmsm_hil/protocol/links/shared_bus.py; the C loop's
        nl_bus_frame.) Else it is counted as bus traffic."""
        fid = frame.arbitration_id
        want = self._target_lengths.get(fid)
        if want is None:
            self.bus.foreign += 1
            return False
        ok = len(frame.data) == want  # the target's frames have their length
        if ok and fid in self._command_ids:
            seq, expected = command_seq(frame), self._expected
            ok = (seq == expected and self._reply is None) or (
                expected >= 0 and seq == (expected - 1) & 0xFFFF and not self._prev_answered)
        elif ok and fid == self._fault_id:
            ok = self.bus.fault_plausible(frame, self._controller_id, self._mode)
        if not ok:
            self.bus.suspect += 1
        return ok

    def _ack_plausible(self, ack: ConfigAck) -> bool:
        """A ConfigAck the target can have sent: for a parameter being written, echoing its float32 bit for bit
        (NaN included), whether it accepts or rejects it (docs/protocol.md: the value is echoed either way). A
        rejection with another value is another node's frame: a flood of protocol ids forged one."""
        sent = self._written.get(ack.param_id)
        return sent is not None and _F32.pack(ack.value) == _F32.pack(sent)

    def _silence_hint(self) -> str:
        """Why a target may not answer at all: none on the link, or (authenticated frames) another key."""
        stats = getattr(self.link, "stats", None)
        if not getattr(link_end(self.link), "authenticated", False):
            return "is a target running on this link?"
        failed = int(getattr(stats, "auth_failed", 0) or 0) + int(getattr(stats, "auth_replayed", 0) or 0)
        seen = f"; {failed} frame(s) from it failed authentication here" if failed else ""
        return ("is a target running on this link, with the same key? An authenticating target drops every frame "
                f"of another key{seen}")

    def serve(self) -> None:
        """Take every frame waiting on the link (non-blocking; an in-process target is pumped first)."""
        self._drain()

    def configure(self, parameters: Mapping[ParamId, float] | Mapping[ParamId | FirmwareParamId, float],
                  timeout_s: float = 10.0,
                  resend_s: float = 0.25) -> None:
        """Write every parameter until acknowledged (resending every resend_s of wall time, so a target that is
        still starting up is caught); raises naming a rejected or unacknowledged parameter. A target that runs only
        when polled (the virtual board: `runs_when_polled`, its `pending()` false once it has nothing left to run)
        is resent to when it has stopped without answering, never by wall time, so that the frames it gets, and
        so its state at the first period, do not depend on how busy the host is."""
        params: dict[int, float] = dict(parameters.items())  # ParamId or FirmwareParamId keys (named)
        self._acks.clear()
        self._written = {int(p): _F32.unpack(_F32.pack(float(v)))[0] for p, v in params.items()}
        bus_before = self.bus.frames
        idle = self._stopped_without_answer()
        # a target behind a link of its own (no in-process pump, not run only when polled) is waited for in the
        # link's receive between sends (blocked, on the wire buses), not by polling: a host that spins while a
        # target starts, or while a silent one is given its timeout_s, takes a core from it
        recv = getattr(self.link, "recv", None) if self.pump is None and idle is None else None
        start = time.perf_counter()
        last_send = -math.inf
        while True:
            now = time.perf_counter()
            pending = [p for p in params if int(p) not in self._acks]
            if not pending:
                break
            if now - start > timeout_s:
                missing = ", ".join(_param_name(p) for p in pending)
                waited = f"no ConfigAck for parameter(s) {missing} within {timeout_s} s"
                starved = bus_starved_reason(self.bus_name, self.bus.frames - bus_before, now - start, waited,
                                             self.backlog) if self.shared else None
                if starved is not None:
                    raise BusStarvedError(starved)
                raise DutViolationError(f"target did not acknowledge parameter(s) {missing} within {timeout_s} s "
                                        f"({self._silence_hint()})")
            if last_send == -math.inf or (idle() if idle is not None else now - last_send >= resend_s):
                for pid in pending:
                    self.link.send(self.codec.encode(ConfigParam(param_id=int(pid), value=float(params[pid]))))
                if last_send > -math.inf:
                    self.config_resent += len(pending)
                last_send = now
            self._drain()
            if recv is not None and not self.backlog and any(int(p) not in self._acks for p in pending):
                wait = min(last_send + resend_s, start + timeout_s) - time.perf_counter()
                frame = recv(wait) if wait > 0 else None
                if frame is not None:
                    self._drain(frame)
        for pid in params:
            ack = self._acks[int(pid)]
            name = _param_name(pid)
            if ack.status != int(Status.OK):
                raise TargetError(f"target rejected parameter '{name}' = {params[pid]}")
            sent = _F32.unpack(_F32.pack(float(params[pid])))[0]
            if ack.value != sent:  # the echo must be the float32 written, bit for bit
                raise DutViolationError(f"target acknowledged parameter '{name}' with value {ack.value!r}, "
                                        f"but {sent!r} was written (ConfigAck echo differs)")

    def _stopped_without_answer(self) -> Callable[[], bool] | None:
        """For a target that runs only when polled (on the host's virtual time), behind the link or the links
        wrapping it: whether it has nothing left to run (`not pending()`); None for any other target."""
        link: Any = self.link
        for _ in range(WRAPPERS_MAX + 1):  # through the wrappers that record or carry its frames (FrameTap, ...)
            pending = getattr(link, "pending", None)
            if getattr(link, "runs_when_polled", False) and pending is not None:
                return lambda: not pending()
            link = getattr(link, "link", None)
            if link is None:
                break
        return None

    def set_setpoint(self, *, enable: bool, mode: int, reference: float, controller_id: int) -> None:
        """Send a setpoint (enable, mode, reference in rad/s or N·m, controller id)."""
        self._controller_id, self._mode = controller_id, mode
        self.link.send(self.codec.encode(Setpoint(enable=enable, mode=mode, reference=reference,
                                                  controller_id=controller_id)))

    def linger(self, seconds: float) -> None:
        """Keep serving the link for `seconds` of wall time (frames still arriving are taken as usual)."""
        end = time.perf_counter() + seconds
        while time.perf_counter() < end:
            self._drain()
            time.sleep(0.001)

    def _on_command(self, cmd: Command) -> None:
        """Keep the genuine reply to the last Measurement; anything else is a finding (or a late reply)."""
        seq = cmd.seq
        if seq == self._expected:
            if self._reply is None:
                self._reply = cmd
            else:
                self.anomalies.append((SEQUENCE, describe(cmd), f"a second Command for seq {seq}"))
        elif seq == (self._expected - 1) & 0xFFFF and not self._prev_answered:
            self.stale_commands += 1  # the previous period's reply, after it was declared missing
            self._prev_answered = True
        else:
            self.anomalies.append((SEQUENCE, describe(cmd), f"seq {seq} while the period's seq is {self._expected}"))

    def send_measurement(self, m: Measurement | Measurement6) -> None:
        """Send one measurement (one or two frames depending on the profile); its seq is now the expected one."""
        if self._expected >= 0:
            self._prev_answered = self._reply is not None
        self._expected = m.seq
        self._reply = None
        self.link.send(self.codec.encode(m))

    def poll_command(self, seq: int) -> Command | None:
        """Non-blocking: the genuine Command answering measurement ``seq`` if it has arrived."""
        self._drain()
        return self._reply if seq == self._expected else None

    def take_anomalies(self) -> list[tuple[str, str, str]]:
        """Contract findings since the last call, frames the decoder rejected included: malformed frames
        (length, value) as `frame`, Command parts with an old or repeated seq as `sequence`."""
        st = self.decoder.stats
        malformed = st.bad_length + st.bad_value
        out_of_seq = st.stale + st.duplicate + st.out_of_order + st.mixed_seq
        if malformed != self._malformed:
            self.anomalies.append((FRAME, "frames from the target", f"{malformed - self._malformed} frame(s) "
                                   f"rejected by the decoder (bad_length {st.bad_length}, bad_value {st.bad_value})"))
            self._malformed = malformed
        if out_of_seq != self._out_of_seq:
            self.anomalies.append((SEQUENCE, "frames from the target", f"{out_of_seq - self._out_of_seq} frame(s) "
                                   f"with an old or repeated seq (stale {st.stale}, duplicate {st.duplicate}, "
                                   f"out_of_order {st.out_of_order}, mixed_seq {st.mixed_seq})"))
            self._out_of_seq = out_of_seq
        out, self.anomalies = self.anomalies, []
        return out
