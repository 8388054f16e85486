"""hiludp talks only to its peer: the peer-address filter, the session handshake of docs/protocol.md ("UDP
datagrams and session handshake"), the payload-length rule, and free ports for spawned targets."""

from __future__ import annotations

import binascii
import socket
import struct
from collections.abc import Callable, Iterator

import can
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from pmsm_hil.protocol.errors import LinkError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links import BusLink, link_kind, parse_spec
from pmsm_hil.protocol.links.wire_bus import HilUdpBus, free_udp_ports
from tests.protocol.wire_oracle import FLAG_BRS, FLAG_FD

Opener = Callable[..., BusLink]
HOST = "127.0.0.1"


class RawPeer:
    """A hand-written UDP end, built only from the wire format in docs/protocol.md."""

    def __init__(self, port: int, remote: int) -> None:
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.bind((HOST, port))
        self.sock.settimeout(2.0)
        self.remote = (HOST, remote)
        self.seq = 0

    def control(self, kind: int, session: int) -> None:
        self.sock.sendto(struct.pack("<I4sBBI", 0, b"HILS", kind, 1, session), self.remote)

    def frame(self, session: int, arb: int, data: bytes, flags: int = FLAG_FD | FLAG_BRS) -> None:
        body = struct.pack("<IBBB", arb, flags, self.seq & 0xFF, len(data)) + data
        self.raw(struct.pack("<I", session) + body + binascii.crc_hqx(body, 0xFFFF).to_bytes(2, "big"))
        self.seq += 1

    def raw(self, datagram: bytes) -> None:
        self.sock.sendto(datagram, self.remote)

    def read_control(self) -> tuple[int, int]:
        """(type, session) of the next control datagram."""
        dgram = self.sock.recv(2048)
        zero, magic, kind, version, session = struct.unpack("<I4sBBI", dgram)
        assert (zero, magic, version) == (0, b"HILS", 1)
        return kind, session


@pytest.fixture
def ports() -> list[int]:
    return free_udp_ports(3)


@pytest.fixture
def raw_peer(ports: list[int]) -> Iterator[RawPeer]:
    peer = RawPeer(ports[1], ports[0])
    yield peer
    peer.sock.close()


def test_plugin_ends_agree_a_session_without_settings(ports: list[int]) -> None:
    a, b, _ = ports
    with can.Bus(interface="hiludp", channel=f"{a}:{b}") as x, can.Bus(interface="hiludp", channel=f"{b}:{a}") as y:
        assert isinstance(x, HilUdpBus) and isinstance(y, HilUdpBus)
        assert x.session == y.session == 0
        x.send(can.Message(arbitration_id=0x200, data=bytes(7), is_extended_id=False))
        assert y.recv(2.0) is not None and y.session != 0
        y.send(can.Message(arbitration_id=0x211, data=bytes(6), is_extended_id=False))
        assert x.recv(2.0) is not None
        assert x.session == y.session != 0
        assert x.link_stats.session_dropped == y.link_stats.session_dropped == 0


def test_host_waits_for_the_peer_to_adopt_its_session(links: Opener, raw_peer: RawPeer, ports: list[int]) -> None:
    a, b, _ = ports
    host = links(f"udp:{a}:{b}", "host")
    bus = host.bus
    assert isinstance(bus, HilUdpBus)
    bus.propose()
    kind, session = raw_peer.read_control()
    assert (kind, session) == (1, bus.session) and not bus.established
    raw_peer.control(2, session)  # ACK
    bus.wait_session(2.0)
    assert bus.established
    raw_peer.frame(session, 0x110, bytes(8), flags=0)
    assert host.recv(1.0) == Frame(0x110, bytes(8), False)


def test_other_senders_and_other_sessions_are_dropped_and_counted(links: Opener, raw_peer: RawPeer,
                                                                  ports: list[int]) -> None:
    """The socket is connect()ed to the peer when it opens: the kernel never delivers another sender's datagrams,
    before the session as after it (`foreign_dropped` stays 0: they never reach the socket)."""
    a, b, c = ports
    host = links(f"udp:{a}:{b}", "host")
    bus = host.bus
    assert isinstance(bus, HilUdpBus) and bus.connected
    forger = RawPeer(c, a)  # another local socket, even one that knows the session
    try:
        forger.control(1, 6)  # a HELLO before the peer's
        forger.frame(6, 0x200, bytes(7), flags=0)
        assert host.recv(0.05) is None and bus.session == 0
        raw_peer.control(1, 7)  # HELLO: the host adopts session 7 and acks
        assert host.recv(0.2) is None
        assert raw_peer.read_control() == (2, 7)
        forger.frame(7, 0x200, bytes(7), flags=0)
        forger.control(1, 8)
        raw_peer.frame(9, 0x200, bytes(7), flags=0)  # the right peer, another session
        raw_peer.raw(struct.pack("<IBBB", 0x200, 0, 0, 7) + bytes(7))  # the pre-session format: malformed
        raw_peer.frame(7, 0x210, bytes(5), flags=0)
        assert host.recv(1.0) == Frame(0x210, bytes(5), False)
        assert host.recv(0.05) is None
    finally:
        forger.sock.close()
    s = host.stats
    assert (s.foreign_dropped, s.session_dropped, s.framing_errors, s.frames_rx) == (0, 1, 1, 1)
    raw_peer.control(1, 11)  # the peer starts a new run: the old session is stale from now on
    raw_peer.frame(11, 0x200, bytes(7), flags=0)
    raw_peer.frame(7, 0x210, bytes(5), flags=0)
    assert host.recv(1.0) == Frame(0x200, bytes(7), False)
    assert host.recv(0.05) is None and host.stats.session_dropped == 2


@pytest.mark.parametrize("role", ["host", "target"])
def test_junk_from_another_address_cannot_crowd_out_the_peer(role: str, links: Opener, raw_peer: RawPeer,
                                                             ports: list[int]) -> None:
    """5000 junk datagrams from another local socket, sent before the peer's frame and not read meanwhile (more
    than the socket buffer holds: unconnected, the kernel would drop the peer's frame) — the frame arrives and
    the junk was never delivered nor counted as a drop of the socket. The reported failure, without timing."""
    a, b, c = ports
    end = links(f"udp:{a}:{b}", role)
    bus = end.bus
    assert isinstance(bus, HilUdpBus)
    if role == "host":
        bus.propose()
        assert raw_peer.read_control() == (1, bus.session)
        raw_peer.control(2, bus.session)
        bus.wait_session(2.0)
        session = bus.session
    else:
        session = 0x1234
        raw_peer.control(1, session)  # the host's HELLO: the target adopts it, acks and connects
        assert end.recv(0.2) is None and raw_peer.read_control() == (2, session)
    assert bus.connected and bus.established
    junk = RawPeer(c, a)
    try:
        for i in range(5000):
            junk.frame(session, 0x100 + (i & 0xFF), bytes(64))
    finally:
        junk.sock.close()
    raw_peer.frame(session, 0x210, bytes(5), flags=0)
    assert end.recv(1.0) == Frame(0x210, bytes(5), False)
    assert end.recv(0.05) is None
    assert (end.stats.foreign_dropped, end.stats.frames_rx, bus.socket_drops()) == (0, 1, 0)


def test_junk_before_the_session_never_reaches_the_socket(links: Opener, raw_peer: RawPeer, ports: list[int]) -> None:
    """The target's socket is connected before any HELLO: a flood before the handshake cannot crowd it out."""
    a, b, c = ports
    end = links(f"udp:{a}:{b}", "target")
    bus = end.bus
    assert isinstance(bus, HilUdpBus) and bus.connected
    junk = RawPeer(c, a)
    try:
        for _ in range(5000):
            junk.control(1, 99)
    finally:
        junk.sock.close()
    raw_peer.control(1, 0x77)
    assert end.recv(0.2) is None and raw_peer.read_control() == (2, 0x77) and bus.session == 0x77
    assert end.stats.foreign_dropped == 0 and bus.socket_drops() == 0


def test_a_refused_datagram_is_a_send_error_not_an_exception(links: Opener, raw_peer: RawPeer,
                                                             ports: list[int]) -> None:
    """Connected, an ICMP port unreachable for an earlier datagram comes back as ECONNREFUSED: counted as a send
    error, and the link goes on (the peer gone is the contract's business: a missing Command)."""
    a, b, _ = ports
    host = links(f"udp:{a}:{b}", "host")
    raw_peer.control(1, 5)
    assert host.recv(0.2) is None and raw_peer.read_control() == (2, 5)
    raw_peer.sock.close()  # the peer's port is closed now
    host.send([Frame(0x200, bytes(7), False)])  # refused by the kernel: ICMP port unreachable
    assert host.recv(0.05) is None
    host.send([Frame(0x200, bytes(7), False)])
    assert host.stats.send_errors >= 1 and host.stats.framing_errors == 0 and host.stats.frames_tx == 2


def test_a_proposal_clash_ends_in_one_session(ports: list[int]) -> None:
    a, b, _ = ports
    with HilUdpBus(f"{a}:{b}") as x, HilUdpBus(f"{b}:{a}") as y:
        x.propose()
        y.propose()
        expected = max(x.session, y.session)
        for _ in range(100):
            x.poll_frame()
            y.poll_frame()
            if x.established and y.established:
                break
        assert x.session == y.session == expected


def test_no_session_is_an_error_naming_the_peer(links: Opener, raw_peer: RawPeer, ports: list[int]) -> None:
    a, b, c = ports
    silent = links(f"udp:{a}:{c}", "host")
    with pytest.raises(LinkError, match=rf"no answer from the peer at 127\.0\.0\.1:{c} within 0\.3 s"):
        silent.bus.wait_session(0.3)
    foreign = links(f"udp:{c}:{b}", "host")
    raw_peer.remote = (HOST, c)
    raw_peer.raw(struct.pack("<IBBB", 0x110, 0, 0, 8) + bytes(8))  # answers in the old format
    with pytest.raises(LinkError, match=rf"peer at 127\.0\.0\.1:{b} answers without the hiludp session handshake"):
        foreign.bus.wait_session(0.3)


@pytest.mark.parametrize(("flags", "length", "ok"), [
    (0, 8, True), (0, 9, False), (FLAG_FD, 12, True), (FLAG_FD, 13, False), (FLAG_FD, 64, True), (FLAG_FD, 65, False),
])
def test_payload_length_rule(links: Opener, raw_peer: RawPeer, ports: list[int], flags: int, length: int,
                             ok: bool) -> None:
    a, b, _ = ports
    host = links(f"udp:{a}:{b}", "host")
    raw_peer.control(1, 5)
    raw_peer.frame(5, 0x300, bytes(length), flags=flags)
    got = host.recv(0.3)
    assert (got is not None) == ok
    assert host.stats.framing_errors == (0 if ok else 1)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(garbage=st.lists(st.binary(max_size=90), min_size=1, max_size=20))
def test_malformed_datagrams_are_counted_never_raise(raw_peer: RawPeer, ports: list[int],
                                                     garbage: list[bytes]) -> None:
    assume(not any(g.startswith(b"\0\0\0\0HILS") or g.startswith(struct.pack("<I", 3)) for g in garbage))
    a, b, _ = ports
    with HilUdpBus(f"{a}:{b}") as bus:
        raw_peer.control(1, 3)
        for g in garbage:
            raw_peer.raw(g)
        raw_peer.frame(3, 0x108, bytes(16))
        link = BusLink(bus, "udp")
        assert link.recv(1.0) == Frame(0x108, bytes(16), True)
        s = bus.link_stats
        assert s.framing_errors + s.session_dropped == len(garbage) and s.frames_rx == 1
        raw_peer.sock.recv(2048)  # the ACK


def test_spawned_udp_without_ports_takes_free_ports() -> None:
    ls = parse_spec("udp,fd=true")
    specs = link_kind(ls).mirror("udp,fd=true", ls)
    host_ports = specs.host.split(",")[0].split(":")[1:]
    target_ports = specs.target.split(",")[0].split(":")[1:]
    assert host_ports == target_ports[::-1] and specs.target.endswith(",fd=true")
    assert not {"47310", "47311"} & set(host_ports) and host_ports[0] != host_ports[1]


def test_a_corrupted_datagram_fails_its_crc_and_is_dropped(raw_peer: RawPeer, ports: list[int]) -> None:
    """The UDP link's own check: CRC-16 (CCITT, init 0xFFFF) over header + payload, big endian, last."""
    a, b, _ = ports
    with HilUdpBus(f"{a}:{b}") as bus:
        raw_peer.control(1, 3)
        body = struct.pack("<IBBB", 0x108, 3, 0, 16) + bytes(16)
        crc = binascii.crc_hqx(body, 0xFFFF).to_bytes(2, "big")
        flipped = bytearray(body)
        flipped[9] ^= 0x10  # one payload bit on the way
        raw_peer.raw(struct.pack("<I", 3) + bytes(flipped) + crc)
        raw_peer.raw(struct.pack("<I", 3) + body + crc)
        link = BusLink(bus, "udp")
        assert link.recv(1.0) == Frame(0x108, bytes(16), True)
        assert link.recv(0.05) is None
        assert bus.link_stats.crc_errors == 1 and bus.link_stats.frames_rx == 1
        raw_peer.sock.recv(2048)  # the ACK
