"""A shared CAN bus (src/pmsm_hil/protocol/links/shared_bus.py, src/pmsm_hil/hil/runner/c/loop.c from_target_node):
other nodes' frames are counted as bus traffic (`bus_foreign_frames`, `bus_suspect_frames`), never taken as the
target's; a flood that starves the run ends naming the bus, never the target. Host-side: a python-can `virtual` bus
marked `shared=true`, an in-process target served through the C loop's callback link, and a flooding thread of random
and of protocol ids (the same logic runs on every CAN link; tests/runner/test_bus_flood_vcan.py runs it on vcan0
under a measured flood in the CI's VM)."""

from __future__ import annotations

import contextlib
import random
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from typing import Any, Self

import can
import pytest

from pmsm_hil.hil.runner import loop_run
from pmsm_hil.hil.runner.contract import EndCode
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.target_client import DRAIN_MAX, TargetClient
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.ids import ParamId, Status
from pmsm_hil.protocol.links.link import open_link
from pmsm_hil.protocol.links.shared_bus import (
    BusTraffic,
    bus_starved_reason,
    command_ids,
    fault_target_id,
    is_shared_bus,
    target_ids,
)
from pmsm_hil.protocol.messages import ConfigAck
from tests.runner.test_loop import _three

#: the ids the target sends: a flood of them with random data is what the host must not take as the target's
TARGET_IDS = sorted(target_ids())


class _InThread:
    """`run` in a daemon thread from `with` entry; on exit `_stop` is set, the thread joined (up to `join_s` [s])
    and `close()` called."""

    def __init__(self, run: Callable[[], None], name: str, join_s: float) -> None:
        self._stop = threading.Event()
        self._join_s = join_s
        self._thread = threading.Thread(target=run, name=name, daemon=True)

    def close(self) -> None:
        """Release what the thread used (after it has ended)."""

    def __enter__(self) -> Self:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(self._join_s)
        self.close()


class Flood(_InThread):
    """A thread sending random frames on a virtual channel: `ids` "random" (any 11-bit id) or "protocol" (the
    target's ids), `rate` frames/s (0: as fast as it can)."""

    def __init__(self, channel: str, ids: str, rate: float, seed: int = 7) -> None:
        self.bus = can.Bus(interface="virtual", channel=channel, protocol=can.CanProtocol.CAN_FD)
        self.ids, self.rate, self.rng = ids, rate, random.Random(seed)
        self.sent = 0
        super().__init__(self._run, "bus-flood", 5.0)

    def _frame(self) -> can.Message:
        rng = self.rng
        fid = rng.choice(TARGET_IDS) if self.ids == "protocol" else rng.randrange(0x800)
        n = rng.choice((2, 6, 8)) if self.ids == "random" else rng.choice((6, 8, 20, 24))
        return can.Message(arbitration_id=fid, data=bytes(rng.randrange(256) for _ in range(n)),
                           is_extended_id=False, is_fd=n > 8)

    def _run(self) -> None:
        period = 1.0 / self.rate if self.rate else 0.0
        t_next = time.perf_counter()
        while not self._stop.is_set():
            self.bus.send(self._frame())
            self.sent += 1
            if period:
                t_next += period
                delay = t_next - time.perf_counter()
                if delay > 0:
                    time.sleep(delay)
            elif self.sent % 64 == 0:
                time.sleep(0)  # let the loop's Python callbacks have the GIL

    def close(self) -> None:
        self.bus.shutdown()


@pytest.fixture
def through_python_link(monkeypatch: pytest.MonkeyPatch) -> None:
    """The in-process Python target on the virtual bus itself (not the C core without a bus), reached through
    the C loop's callback link: the flood reaches the host's receive."""
    monkeypatch.setattr(loop_run, "in_core", lambda cfg: False)


def _run_flooded(channel: str, ids: str, rate: float, **overrides: Any) -> dict[str, Any]:
    cfg = replace(_three(link=f"virtual:{channel},shared=true", target="inproc", loop="native"), **overrides)
    with Flood(channel, ids, rate) as flood:
        res = run_closed_loop(cfg)
    assert flood.sent > 0
    return res.metrics


def _never_the_target(m: dict[str, Any]) -> None:
    """Completed, or ended naming the bus (exit 3): never a DUT finding, a target fault or a silent target."""
    assert m["end_code"] in (EndCode.COMPLETED, EndCode.SAFETY_STOP), m["end_reason"]
    if m["end_code"] == EndCode.SAFETY_STOP:
        assert m["end_reason"].startswith("bus virtual:"), m["end_reason"]
    assert m["dut_violations"] == 0, m["dut_violation_list"][:3]


@pytest.mark.parametrize("ids", ["random", "protocol"])
def test_a_1k_frames_per_s_flood_never_blames_the_target(through_python_link: None, ids: str) -> None:
    """1 k frames/s of random ids, or of the target's own ids with random data: counted as the bus's."""
    m = _run_flooded(f"flood-{ids}", ids, 1000.0)
    _never_the_target(m)
    assert m["bus_foreign_frames"] + m["bus_suspect_frames"] > 0
    if ids == "protocol":
        assert m["bus_suspect_frames"] > 0  # Commands for no open seq, implausible faults and acks


def test_a_full_rate_flood_ends_within_the_lockstep_limits(through_python_link: None) -> None:
    """As fast as a thread can send: the run completes or ends naming the bus, within the lockstep timeout
    times the watchdog's periods (plus the set-up), never hanging in the receive."""
    t0 = time.perf_counter()
    m = _run_flooded("flood-full", "protocol", 0.0, lockstep_timeout_s=0.5)
    _never_the_target(m)
    assert time.perf_counter() - t0 < 120.0  # generous: a loaded machine; the bug was no ending at all


def test_no_flood_no_bus_counts(through_python_link: None) -> None:
    """A quiet shared bus: the run as ever, both counters 0; a link that is not shared: null."""
    cfg = _three(link="virtual:quiet,shared=true", target="inproc", loop="native")
    m = run_closed_loop(cfg).metrics
    assert m["end_code"] == 0 and m["bus_foreign_frames"] == 0 and m["bus_suspect_frames"] == 0
    m = run_closed_loop(replace(cfg, link="virtual:quiet2")).metrics
    assert m["bus_foreign_frames"] is None and m["bus_suspect_frames"] is None


def test_which_links_are_shared() -> None:
    assert is_shared_bus("socketcan:vcan0,fd=true") and is_shared_bus("pcan:PCAN_USBBUS1")
    assert not is_shared_bus("virtual") and is_shared_bus("virtual:x,shared=true")
    assert not is_shared_bus("socketcan:can0,shared=false") and not is_shared_bus("udp")


class _Quiet:
    """A link whose frames are the test's: `poll` hands them out one by one."""

    def __init__(self, frames: list[Frame]) -> None:
        self.frames, self.sent = frames, []  # type: ignore[var-annotated]
        self.shared = True
        self.description = "test:bus"

    def poll(self) -> Frame | None:
        return self.frames.pop(0) if self.frames else None

    def send(self, frames: Any) -> None:
        self.sent.extend(frames)


def _client(frames: list[Frame]) -> TargetClient:
    return TargetClient(_Quiet(frames), FrameCodec("canfd"))  # type: ignore[arg-type]


def test_a_random_fault_frame_is_not_the_targets() -> None:
    """FaultTarget's id with another node, a code outside Status, not_implemented naming another controller or
    invalid_config naming no Mode (the VM's "target fault code 5 (detail 28)": the target answering another
    node's Setpoint): suspect, not a target fault (the reported "target fault code 116")."""
    fid = fault_target_id()
    frames = [Frame(fid, bytes([1, 116, 0, 0, 0, 0]), False), Frame(fid, bytes([9, 1, 0, 0, 0, 0]), False),
              Frame(fid, bytes([1, 6, 77, 0, 0, 0]), False), Frame(fid, bytes([1, 6, 1, 0, 0, 0]), False),
              Frame(fid, bytes([1, 5, 28, 0, 0, 0]), False), Frame(fid, bytes([1, 5, 1, 0, 0, 0]), False)]
    client = _client(frames)
    client._controller_id = 1
    client.serve()
    assert [f.code for f in client.faults] == [6, 5] and client.bus.suspect == 4


def test_commands_for_no_open_seq_are_suspect_not_findings() -> None:
    """Command frames whose seq answers no Measurement sent: suspect, no sequence finding; the genuine reply is
    taken, a second one is suspect."""
    codec = FrameCodec("canfd")
    from pmsm_hil.protocol.messages import Command, Measurement
    client = _client([])
    client.send_measurement(Measurement(seq=5, i_a=0.0, i_b=0.0, i_c=0.0, theta_e=0.0, omega_m=0.0, vdc=48.0))
    cmd = Command(seq=5, states=(0,), durations_ns=(100_000,))
    junk = Command(seq=4000, states=(0,), durations_ns=(100_000,))
    client.link.frames = [*codec.encode(junk), *codec.encode(cmd), *codec.encode(cmd), Frame(0x123, b"xx", False)]
    assert client.poll_command(5) is not None
    assert client.take_anomalies() == []
    assert client.bus == BusTraffic(foreign=1, suspect=2)
    assert all(fid in command_ids() for fid in {f.arbitration_id for f in codec.encode(cmd)})


def test_the_starved_reason_names_the_bus_and_its_rate() -> None:
    assert bus_starved_reason("socketcan:vcan0", 100, 1.0, "x") is None  # 100 frames/s: the target's
    reason = bus_starved_reason("socketcan:vcan0", 1200, 1.0, "lockstep: no Command for seq 7")
    assert reason is not None and reason.startswith("bus socketcan:vcan0: 1.2 k frames/s")
    assert "seq 7" in reason


def test_open_link_takes_the_shared_option_off_the_bus() -> None:
    link = open_link("virtual:opt,shared=true")
    try:
        assert link.shared
    finally:
        link.close()


@pytest.fixture(autouse=True)
def _no_leaked_threads() -> Iterator[None]:
    yield
    assert not any(t.name == "bus-flood" and t.is_alive() for t in threading.enumerate())


class ThreadTarget(_InThread):
    """A Python target (SimTarget) in a thread on a virtual channel, answering its first `silent_after`
    Measurements: to the host a target in another process (`--target external`), whose replies take wall time."""

    def __init__(self, spec: str, silent_after: int | None) -> None:
        from pmsm_hil.sim_target.target import SimTarget

        self.link = open_link(spec, "target")
        self.target = SimTarget(self.link, FrameCodec("canfd"), silent_after=silent_after)
        super().__init__(lambda: self.target.run_forever(self._stop.is_set), "bus-target", 10.0)

    def close(self) -> None:
        self.link.close()


#: the flooded case is a `timing` test: its flood (a thread of this process, beside the target's thread) must reach
#: the starving rate the host's verdict names; beside load 12 it did not, and the host rightly saw a target that
#: stopped answering on a bus that was not starved (exit 4, rule `missing`)
@pytest.mark.parametrize("flood", [pytest.param(True, marks=pytest.mark.timing), False])
def test_a_silent_target_on_a_flooded_bus_ends_naming_the_bus(flood: bool) -> None:
    """The target stops answering while other nodes flood the bus at full rate: the ending names the bus and its
    rate (exit 3), not the target; on a quiet shared bus the same silence is the target's (rule `missing`)."""
    spec = f"virtual:starved{flood},shared=true"
    cfg = replace(_three(link=spec, target="external", loop="native"), lockstep_timeout_s=0.5)
    with ThreadTarget(spec, silent_after=100), contextlib.ExitStack() as stack:
        if flood:
            stack.enter_context(Flood(f"starved{flood}", "random", 0.0))
        m = run_closed_loop(cfg).metrics
    if flood:
        assert m["end_code"] == EndCode.SAFETY_STOP, m["end_reason"]
        assert m["end_reason"].startswith(f"bus {spec}: "), m["end_reason"]
        # the flood's rate, or (random ids) frames of the host's ids from another node that reached the target
        assert "(lockstep: no Command for seq " in m["end_reason"]  # 100, or earlier under load
        assert "starved the run" in m["end_reason"] or "of the host's ids" in m["end_reason"]
        assert m["bus_foreign_frames"] > 0
        assert m["dut_violations"] == 0  # the `missing` finding the bus took over is not the target's
    else:
        assert m["end_code"] == EndCode.DUT_VIOLATION and "missing: no Command for seq " in m["end_reason"]
        assert m["bus_foreign_frames"] == 0
    assert m["dut_violations_by_rule"]["frame"] == 0 and m["dut_violations_by_rule"]["sequence"] == 0


def test_the_c_socketcan_receive_ends_on_a_queue_that_never_empties() -> None:
    """The C SocketCAN link (on a socketpair carrying its frames): past the deadline it returns at most
    NL_DRAIN_MAX (= the Python links' DRAIN_MAX) frames in a row, then 0, however many are queued (a
    full-rate flood that never ended: the loop's receives kept finding frames)."""
    import socket

    from can.interfaces.socketcan.socketcan import build_can_frame

    from pmsm_hil.hil.runner.core_link import native_lib

    ffi, lib = native_lib()
    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    with a, b:
        a.setblocking(False)
        b.setblocking(False)
        frame = build_can_frame(can.Message(arbitration_id=0x123, data=bytes(8), is_extended_id=False))
        queued = 0
        try:
            while queued < 4 * DRAIN_MAX:
                a.send(frame)
                queued += 1
        except BlockingIOError:
            pass
        assert queued > DRAIN_MAX  # more than one drain's worth
        s = ffi.new("nl_socketcan_t *")
        s.fd, s.fd_frames = b.fileno(), 1
        f = ffi.new("hil_core_frame_t *")
        got = 0
        while lib.nl_socketcan_recv(s, f, 0) > 0:
            got += 1
        assert got == DRAIN_MAX  # a drain (deadline 0) ends with frames still queued
        past = time.clock_gettime_ns(time.CLOCK_MONOTONIC) - 1
        got = 0
        while lib.nl_socketcan_recv(s, f, past) > 0:
            got += 1
        assert got == min(DRAIN_MAX, queued - DRAIN_MAX)


class _Endless(_Quiet):
    """A shared bus whose receive queue never empties: another node's frame on every poll."""

    def poll(self) -> Frame | None:
        return Frame(0x123, b"\x00" * 8, False)


def test_a_safe_stop_behind_a_flood_names_the_bus() -> None:
    """The confirmation may be queued behind other nodes' frames the host cannot read fast enough: the safe stop
    is not confirmed (exit 3 stands) but the reason names the bus, not a silent target; on a quiet bus it stays
    the target's."""
    from pmsm_hil.hil.runner.safe_stop import disable_and_confirm

    stop = disable_and_confirm(TargetClient(_Endless([]), FrameCodec("canfd")), 1,  # type: ignore[arg-type]
                               timeout_s=0.05)
    assert not stop.confirmed and stop.observed.startswith("bus test:bus: "), stop.observed
    assert "the receive queue never emptied" in stop.observed and "HeartbeatTarget" in stop.observed
    quiet = disable_and_confirm(_client([]), 1, timeout_s=0.05)
    assert not quiet.confirmed and quiet.observed.startswith("no HeartbeatTarget"), quiet.observed


def test_a_forged_rejection_of_a_parameter_being_written_is_not_the_targets() -> None:
    """Another node's ConfigAck naming a parameter being written, with another value and status invalid (a flood of
    protocol ids in the CI VM: "target rejected parameter 'pole_pairs' = 3.0"): suspect; the target's own echo,
    accepting or rejecting, is taken."""
    codec = FrameCodec("canfd")
    client = _client([])
    client._written = {int(ParamId.POLE_PAIRS): 3.0, int(ParamId.RS): 0.5}
    forged = ConfigAck(param_id=int(ParamId.POLE_PAIRS), value=1.5e-7, status=int(Status.INVALID_CONFIG))
    genuine = ConfigAck(param_id=int(ParamId.POLE_PAIRS), value=3.0, status=int(Status.OK))
    rejected = ConfigAck(param_id=int(ParamId.RS), value=0.5, status=int(Status.INVALID_CONFIG))
    client.link.frames = [*codec.encode(forged), *codec.encode(genuine), *codec.encode(rejected)]
    client.serve()
    assert client.bus.suspect == 1
    assert client._acks[int(ParamId.POLE_PAIRS)].status == int(Status.OK)
    assert client._acks[int(ParamId.RS)].status == int(Status.INVALID_CONFIG)
