"""The native loop's SocketCAN link (src/pmsm_hil/hil/runner/c/links/loop_socketcan.c). This machine's kernel has no
SocketCAN (no vcan), so the C link is tested on a SOCK_SEQPACKET socketpair carrying the same `struct can_frame` /
`struct canfd_frame` bytes python-can's socketcan interface writes and reads: its frames are python-can's, byte
for byte, and a run of the native loop over the pair — against a Python target (SimTarget) or the C target core
(nt_serve) on the other end — gives the Python loop's records and metrics. With a vcan0 interface, the same
comparison runs on it (`hil run --link socketcan:vcan0 --target spawn`, the spawned target native too)."""

from __future__ import annotations

import contextlib
import socket
import threading
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import can
import pytest
from can import CanProtocol
from can.interfaces.socketcan.socketcan import build_can_frame, dissect_can_frame

from pmsm_hil.hil.runner.core_link import native_lib
from pmsm_hil.hil.runner.run import RunResult, run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.wire import COUNTERS, WireHandle
from pmsm_hil.hil.runner.wire_kinds import NATIVE_WIRES
from pmsm_hil.hil.runner.wire_socketcan import SOCKETCAN_WIRE
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.links import LINK_KINDS, LinkKind, link_profile, open_link
from pmsm_hil.protocol.links.spec import LinkSpec, Role
from pmsm_hil.sim_target.target import SimTarget
from tests.runner.test_loop import SENSORS, _mirrored, _six, _three
from tests.runner.test_wire_udp import _assert_same, _without_resends

CAN_MTU, CANFD_MTU = 16, 72
CAN_EFF_FLAG, CAN_RTR_FLAG, CAN_ERR_FLAG = 0x80000000, 0x40000000, 0x20000000


class SeqpacketCanBus(can.BusABC):
    """Test-only python-can bus on one end of a SOCK_SEQPACKET socketpair (channel: its descriptor), moving
    frames with python-can's own SocketCAN packing (build_can_frame / dissect_can_frame), as its socketcan
    interface does on a CAN_RAW socket."""

    def __init__(self, channel: Any = None, *, fd: bool = False, **kwargs: Any) -> None:
        self._sock = socket.socket(fileno=int(channel))
        self._sock.setblocking(False)
        self.channel_info = f"seqpacket fd {channel}"
        super().__init__(channel=channel, **kwargs)
        self._can_protocol = CanProtocol.CAN_FD if fd else CanProtocol.CAN_20

    def fileno(self) -> int:
        return self._sock.fileno()

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        try:
            self._sock.send(build_can_frame(msg))
        except OSError as exc:
            raise can.CanOperationError(str(exc)) from exc

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        try:
            cf = self._sock.recv(CANFD_MTU)
        except BlockingIOError:
            return None, False
        if not cf:  # the other end closed
            return None, False
        can_id, dlc, flags, data = dissect_can_frame(cf)
        extended = bool(can_id & CAN_EFF_FLAG)
        return can.Message(arbitration_id=can_id & (0x1FFFFFFF if extended else 0x7FF), is_extended_id=extended,
                           is_remote_frame=bool(can_id & CAN_RTR_FLAG), is_error_frame=bool(can_id & CAN_ERR_FLAG),
                           is_fd=len(cf) == CANFD_MTU, bitrate_switch=bool(flags & 1), dlc=dlc, data=data), False

    def shutdown(self) -> None:
        super().shutdown()
        self._sock.close()


def _open_seqcan(ls: LinkSpec, role: Role) -> tuple[can.BusABC, str]:
    fd = ls.options.get("fd", False)
    return SeqpacketCanBus(ls.channel, fd=fd is True or str(fd).lower() == "true"), f"seqcan:{ls.channel}"


@pytest.fixture
def seqcan(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """The `seqcan:FD` link kind for this test, driven by the native loop as a SocketCAN link."""
    monkeypatch.setitem(LINK_KINDS, "seqcan", LinkKind("seqcan", "a socketpair end (tests)", _open_seqcan))
    wire = replace(SOCKETCAN_WIRE, bus_of=lambda link: getattr(link, "bus", None))
    monkeypatch.setitem(NATIVE_WIRES, "seqcan", wire)
    yield


def _state(fd: int, fd_frames: bool) -> Any:
    ffi, _ = native_lib()
    s = ffi.new("nl_socketcan_t *")
    s.fd, s.fd_frames = fd, 1 if fd_frames else 0
    return s


def _deadline(seconds: float) -> int:
    return time.clock_gettime_ns(time.CLOCK_MONOTONIC) + int(seconds * 1e9)


def test_c_frames_are_python_cans_bytes_both_ways() -> None:
    ffi, lib = native_lib()
    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    with a, b:
        b.setblocking(False)
        s = _state(b.fileno(), True)
        sent = [(0x180, bytes(range(1, 13)), True), (0x181, b"\x01\x02\x03", False), (0x7FF, bytes(8), False),
                (0x100, b"", False), (0x182, bytes(range(64)), True)]
        for arb, data, fd in sent:
            f = ffi.new("hil_core_frame_t *", {"id": arb, "len": len(data), "fd": 1 if fd else 0, "data": data})
            assert lib.nl_socketcan_send(s, f) == 0
            want = build_can_frame(can.Message(arbitration_id=arb, data=data, is_fd=fd, bitrate_switch=fd,
                                               is_extended_id=False))
            assert a.recv(CANFD_MTU) == want
        bad = ffi.new("hil_core_frame_t *", {"id": 0x180, "len": 9, "fd": 1})
        assert lib.nl_socketcan_send(s, bad) == -1  # 9 bytes is no CAN FD length
        s.fd_frames = 0
        bad.len = 12
        assert lib.nl_socketcan_send(s, bad) == -1  # an FD frame on a classic socket
        for arb, data, fd in sent:
            a.send(build_can_frame(can.Message(arbitration_id=arb, data=data, is_fd=fd, bitrate_switch=fd,
                                               is_extended_id=False)))
        a.send(build_can_frame(can.Message(arbitration_id=0x1234567, data=b"\x01", is_extended_id=True)))
        a.send(build_can_frame(can.Message(arbitration_id=0x181, is_remote_frame=True, is_extended_id=False,
                                           dlc=2)))
        a.send(build_can_frame(can.Message(arbitration_id=0x4, is_error_frame=True, is_extended_id=False)))
        a.send(bytes(20))  # no frame of either size
        got = []
        f = ffi.new("hil_core_frame_t *")
        while lib.nl_socketcan_recv(s, f, _deadline(0.05)) > 0:
            got.append((int(f.id), bytes(ffi.buffer(f.data, f.len)), bool(f.fd)))
            assert not any(f.data[f.len:64])
        assert got == sent
        stats = {name: int(getattr(s.stats, name)) for name in COUNTERS}
        assert (stats["frames_tx"], stats["frames_rx"], stats["send_errors"], stats["ignored"],
                stats["framing_errors"]) == (5, 5, 2, 3, 1)
        assert sum(stats.values()) == 16 and s.stats.blocked >= 1  # nothing else counted; the end waited in ppoll


def test_a_closed_peer_ends_the_receive_and_the_c_target() -> None:
    ffi, lib = native_lib()
    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    with b:
        s = _state(b.fileno(), True)
        a.close()
        f = ffi.new("hil_core_frame_t *")
        assert lib.nl_socketcan_recv(s, f, _deadline(1.0)) == -1
        h = WireHandle(SOCKETCAN_WIRE, ffi, lib, _FdOnly(b.fileno()), target_role=True)
        assert lib.nt_serve(h.link, 0, 0) == lib.NT_END_CLOSED


class _FdOnly:
    """What SOCKETCAN_WIRE reads of a bus: its descriptor and protocol."""

    def __init__(self, fd: int) -> None:
        self._fd = fd
        self.protocol = CanProtocol.CAN_FD

    def fileno(self) -> int:
        return self._fd


@contextlib.contextmanager
def _target_on(spec: str, kind: str) -> Iterator[None]:
    """A target on the socketpair end `spec` in a thread of this process: the Python SimTarget or the C target
    core (nt_serve); it ends when the host closes its end."""
    if kind == "python":
        link = open_link(spec, "target")
        target = SimTarget(link, FrameCodec(link_profile(spec)))
        stop = threading.Event()
        thread = threading.Thread(target=target.run_forever, args=(stop.is_set,), kwargs={"idle_sleep_s": 1e-4})
    else:
        ffi, lib = native_lib()
        link = open_link(spec, "target")
        lib.hil_core_init()
        h = WireHandle(SOCKETCAN_WIRE, ffi, lib, link.bus, target_role=True)  # type: ignore[attr-defined]
        stop = threading.Event()
        thread = threading.Thread(target=lib.nt_serve, args=(h.link, 5_000_000_000, 0))
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join(timeout=10)
        link.close()
    assert not thread.is_alive()


def _run_over_pair(cfg: RunConfig, loop: str, target: str) -> RunResult:
    a, b = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    opts = cfg.link.partition(",")[2]
    tail = f",{opts}" if opts else ""
    with _target_on(f"seqcan:{b.detach()}{tail}", target):
        # a generous lockstep timeout: the target serves in a thread of this process (`external`, no process the
        # host observes apart), so the wait is wall time; at load 12 the default's 0.5 s ended runs early
        return run_closed_loop(replace(cfg, link=f"seqcan:{a.detach()}{tail}", target="external", loop=loop,
                                       lockstep_timeout_s=10.0))


#: the Python loop + Python target's run of each configuration: a lockstep run gives the same records each time, so
#: the cases that compare two native targets with it (`c` and `python` on classic CAN) share one
_PYTHON_RUNS: dict[str, RunResult] = {}


def _python_reference(cfg: RunConfig) -> RunResult:
    key = repr(cfg)
    if key not in _PYTHON_RUNS:
        _PYTHON_RUNS[key] = _run_over_pair(cfg, "python", "python")
    return _PYTHON_RUNS[key]


@pytest.mark.usefixtures("seqcan")
@pytest.mark.parametrize(("make", "link", "target"), [
    (_three, "seqcan,fd=true", "c"), (_three, "seqcan", "c"), (_three, "seqcan", "python"), (_mirrored, "seqcan", "c"),
    (_six, "seqcan", "c"),
])
def test_native_loop_over_socketcan_frames_gives_the_python_loops_records(make: Any, link: str, target: str) -> None:
    """Classic CAN (the Measurement and Command in parts, as the Python codec splits them) and CAN FD."""
    cfg = make(link=link, sensors=SENSORS)
    py = _python_reference(cfg)
    na = _run_over_pair(cfg, "native", target)
    assert py.metrics["loop"] == "python" and na.metrics["loop"] == "native" and na.metrics["loop_note"] is None
    _assert_same(py, na)
    assert _without_resends(na.metrics["link"])["frames_tx"] == _without_resends(py.metrics["link"])["frames_tx"] > 0


@pytest.mark.skipif(not Path("/sys/class/net/vcan0").exists(),
                    reason="no SocketCAN interface vcan0 (kernel without vcan; `ip link add vcan0 type vcan`)")
@pytest.mark.parametrize("link", ["socketcan:vcan0", "socketcan:vcan0,fd=true"])
def test_native_loop_over_vcan_gives_the_python_loops_records(link: str) -> None:
    """On a real SocketCAN interface: the Python loop + Python target and the native loop + native target
    (`hil target --native` on the same interface), each spawned."""
    # a VM under TCG on a loaded host (.ci/vcan-vm) can stall the spawned target past the default 0.5 s: both
    # loops count its own time (a host stall, not a `missing` finding), so the default timeout holds
    runs = [run_closed_loop(replace(_three(link=link), target="spawn", loop=loop)) for loop in ("python", "native")]
    assert runs[1].metrics["loop"] == "native"
    _assert_same(*runs)
