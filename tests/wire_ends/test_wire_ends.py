"""The C wire ends a run opens without python-can (wire_core.py) against the python-can buses they stand for
(wire_bus.py): the same frames, the same counters, and the python-can bus an end becomes when it is asked for."""

from __future__ import annotations

import os
import random
import tty
from collections.abc import Callable, Iterator

import can
import pytest

from pmsm_hil.protocol.errors import LinkError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links import BusLink, open_link
from pmsm_hil.protocol.links.stats import LinkStats
from pmsm_hil.protocol.links.wire_bus import HilSerialBus, HilUdpBus, WireBus
from pmsm_hil.protocol.links.wire_core import SerialEnd, UdpEnd, WireEnd, WireError, free_udp_ports, link_end

#: (arbitration id, data, FD) of the frames both ways: every payload length the wires carry, classic and FD
_RNG = random.Random(35)
_FD_LENGTHS = (*range(9), 12, 16, 20, 24, 32, 48, 64)
FRAMES = [(_RNG.randrange(0x800), _RNG.randbytes(n), fd) for fd, lengths in ((False, range(9)), (True, _FD_LENGTHS))
          for n in lengths] * 3
#: frames a python-can sender puts on the wire that a link skips (and counts as ignored): extended, remote
SKIPPED = [can.Message(arbitration_id=0x1ABCDEF, data=b"\1\2", is_extended_id=True),
           can.Message(arbitration_id=0x123, is_remote_frame=True, dlc=3, is_extended_id=False)]

Pair = Callable[[bool], "tuple[BusLink, BusLink]"]


def _udp_pair(bare: bool) -> tuple[BusLink, BusLink]:
    """Host and target links on a UDP pair: opened as a run opens them (`open_link`: bare ends), or on python-can's
    buses of the same kind (the reference)."""
    a, b = free_udp_ports(2)
    if bare:
        return open_link(f"udp:{a}:{b}", "host"), open_link(f"udp:{b}:{a}", "target")
    return BusLink(HilUdpBus(f"{a}:{b}"), "udp host"), BusLink(HilUdpBus(f"{b}:{a}"), "udp target")


def _pty_pair(bare: bool) -> tuple[BusLink, BusLink]:
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    if bare:
        return open_link(f"serial:fd:{master}", "host"), open_link(f"serial:fd:{slave}", "target")
    return BusLink(HilSerialBus(f"fd:{master}"), "pty host"), BusLink(HilSerialBus(f"fd:{slave}"), "pty target")


@pytest.fixture(params=[_udp_pair, _pty_pair], ids=["udp", "pty"])
def pairs(request: pytest.FixtureRequest) -> Iterator[Pair]:
    """Makes pairs of one kind; every link it made is closed after the test."""
    made: list[BusLink] = []

    def make(bare: bool) -> tuple[BusLink, BusLink]:
        pair: tuple[BusLink, BusLink] = request.param(bare)
        made.extend(pair)
        return pair

    yield make
    for link in made:
        link.close()


def _exchange(host: BusLink, target: BusLink) -> tuple[list[Frame | None], list[Frame | None], dict[str, int]]:
    """Every frame of FRAMES host -> target and back, with the skipped kinds sent through python-can's face of the
    sending end in between; what each end received and both ends' counters."""
    to_target: list[Frame | None] = []
    to_host: list[Frame | None] = []
    for i, (ident, data, fd) in enumerate(FRAMES):
        host.send([Frame(ident, data, fd)])
        to_target.append(target.recv(5.0))
        if i % 10 == 0:
            target.bus.send(SKIPPED[i // 10 % 2])
        target.send([Frame(ident ^ 0x7FF, data[::-1], fd)])
        to_host.append(host.recv(5.0))
    counters = {f"{side}.{name}": int(getattr(link.stats, name))
                for side, link in (("host", host), ("target", target)) for name in LinkStats.__slots__}
    return to_target, to_host, counters


def test_a_bare_end_carries_what_python_cans_bus_carries(pairs: Pair) -> None:
    """The frames received and every C counter, bit for bit, on bare ends and on python-can buses of the same
    kind (the host end stays bare through the exchange: only the target is asked for its bus)."""
    bare_host, bare_target = pairs(True)
    assert type(bare_host.end) in (UdpEnd, SerialEnd) and not isinstance(bare_host.end, can.BusABC)
    got = _exchange(bare_host, bare_target)
    assert type(bare_host.end) in (UdpEnd, SerialEnd)  # never asked for its bus
    want = _exchange(*pairs(False))
    assert got == want
    assert got[0] == [Frame(i, d, fd) for i, d, fd in FRAMES]
    skipped = len(range(0, len(FRAMES), 10))  # received (the C link counts them), then skipped
    assert got[2]["host.ignored"] == skipped and got[2]["host.frames_rx"] == len(FRAMES) + skipped


def test_an_end_asked_for_its_bus_becomes_the_python_can_bus_of_its_kind(pairs: Pair) -> None:
    """`link.bus` of a bare end: the same object on the same C state, now a `HilUdpBus` / `HilSerialBus` (python-can's
    receive, send and errors); its counters carry on; shut down stays shut down."""
    host, target = pairs(True)
    end = host.end
    address, stats = end.c_state_address, end.link_stats
    target.send([Frame(0x101, b"\1\2\3", True)])
    assert host.recv(5.0) == Frame(0x101, b"\1\2\3", True)
    bus = host.bus
    assert bus is end and bus.c_state_address == address and host.end is bus and link_end(host) is bus
    assert isinstance(bus, (HilUdpBus, HilSerialBus)) and isinstance(bus, can.BusABC)
    assert bus.protocol is can.CanProtocol.CAN_FD and bus.link_stats.frames_rx == stats.frames_rx == 1
    target.send([Frame(0x102, b"\4", False)])
    msg = bus.recv(5.0)
    assert msg is not None
    assert (msg.arbitration_id, bytes(msg.data), msg.is_fd, msg.is_rx) == (0x102, b"\4", False, True)
    bus.send(can.Message(arbitration_id=0x103, data=b"\5" * 12, is_fd=True, is_extended_id=False))
    assert target.recv(5.0) == Frame(0x103, b"\5" * 12, True)
    host.close()
    assert bus._is_shutdown and host.bus is bus
    with pytest.raises(can.CanOperationError, match="shut down"):
        bus.send(can.Message(arbitration_id=1))


def test_a_bare_ends_errors_are_link_errors_and_its_bus_raises_python_cans() -> None:
    """A frame the wire cannot carry: a LinkError from the bare end (no python-can), python-can's CanOperationError
    (a LinkError too) from its bus; a bad channel names it either way."""
    a, b = free_udp_ports(2)
    with UdpEnd(f"{a}:{b}", fd=False) as end:
        with pytest.raises(WireError, match="payload length 12 invalid for FD frame") as bare:
            end.send_frame(0x10, bytes(12), True)
        assert not isinstance(bare.value, can.CanError)
    with HilUdpBus(f"{a}:{b}", fd=False) as bus:
        with pytest.raises(can.CanOperationError, match="payload length 12 invalid for FD frame") as face:
            bus.send_frame(0x10, bytes(12), True)
        assert isinstance(face.value, LinkError)
    with pytest.raises(LinkError, match="LOCALPORT:REMOTEPORT"):
        UdpEnd("47310")
    with pytest.raises(LinkError, match="cannot open link 'serial:fd:x'"):
        open_link("serial:fd:x")


def test_own_messages_of_an_end_made_a_bus_are_python_cans() -> None:
    """`receive_own_messages` in the SPEC: the end keeps it, and its bus hands back what it sent (held without
    python-can's Message) as python-can's own bus does, field for field."""
    got = []
    for bare in (True, False):
        a, b = free_udp_ports(2)
        link = open_link(f"udp:{a}:{b},receive_own_messages=true") if bare else \
            BusLink(HilUdpBus(f"{a}:{b}", receive_own_messages=True), "udp")
        peer = open_link(f"udp:{b}:{a}", "target")
        try:
            assert isinstance(link.end, WireBus) is not bare
            sent = [can.Message(arbitration_id=0x2AA, data=b"own", is_fd=True, bitrate_switch=True,
                                is_extended_id=False),
                    can.Message(arbitration_id=0x1F, is_remote_frame=True, dlc=5, is_extended_id=True)]
            for msg in sent:
                link.bus.send(msg)
            back = [link.bus.recv(5.0) for _ in sent]
            got.append([(m.arbitration_id, bytes(m.data), m.dlc, m.is_fd, m.bitrate_switch, m.is_remote_frame,
                         m.is_extended_id, m.is_rx) for m in back if m is not None])
            assert [m.channel for m in back if m is not None] == [f"{a}:{b}"] * 2
            assert peer.recv(5.0) == Frame(0x2AA, b"own", True)
        finally:
            link.close()
            peer.close()
    assert got[0] == got[1] and len(got[0]) == 2 and not got[0][0][-1]


def test_link_end_reads_through_wrappers_without_making_a_bus() -> None:
    """`link_end` finds the end under wrappers that hold the link as `.link`, and leaves a bare end bare."""
    a, b = free_udp_ports(2)
    with open_link(f"udp:{a}:{b}") as link:

        class Wrapper:
            def __init__(self, inner: object) -> None:
                self.link = inner

        assert link_end(Wrapper(Wrapper(link))) is link.end
        assert type(link.end) is UdpEnd and isinstance(link.end, WireEnd)
    assert link_end(object()) is None
