"""Back-to-back link tests: virtual, UDP plugin (one and two processes), serial over a pty pair,
python-can udp_multicast and SocketCAN (skipped with a reason when unavailable)."""

from __future__ import annotations

import binascii
import contextlib
import os
import socket
import tty
from collections.abc import Callable, Iterator
from pathlib import Path

import can
import pytest

from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.errors import LinkError, LinkSpecError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links import BusLink, Link, open_link, parse_spec
from pmsm_hil.protocol.links.echo import STOP_ID
from pmsm_hil.protocol.links.peer import EchoPeer
from pmsm_hil.protocol.messages import Command, Measurement
from tests.protocol.wire_oracle import CONTROL, HELLO, MAGIC, SESSION, VERSION, cobs_encode, encode_packet, pack_frame

Opener = Callable[..., BusLink]


def free_udp_ports(n: int = 2) -> list[int]:
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(n)]
    try:
        for s in socks:
            s.bind(("127.0.0.1", 0))
        return [s.getsockname()[1] for s in socks]
    finally:
        for s in socks:
            s.close()


@pytest.fixture
def pty_pair() -> Iterator[tuple[int, str]]:
    master, slave = os.openpty()
    tty.setraw(slave)
    name = os.ttyname(slave)
    yield master, name
    os.close(slave)
    with contextlib.suppress(OSError):  # already closed by the serial link that owned it
        os.close(master)


def exchange(host: Link, target: Link, profile: str = "canfd") -> None:
    """Measurement host -> target and Command back, through the codec; asserts both arrive intact."""
    codec = FrameCodec(profile)  # type: ignore[arg-type]
    m = Measurement(42, 1.5, -0.75, -0.75, 2.0, 50.0, 48.0, 0)
    c = Command(42, (4, 6), (40000, 60000), 3, 8, 1200, 0)
    host.send(codec.encode(m))
    dec = codec.decoder()
    got = None
    for _ in codec.encode(m):
        fr = target.recv(2.0)
        assert fr is not None, "frame lost"
        got = dec.feed(fr)
    assert isinstance(got, Measurement) and got.seq == 42
    target.send(codec.encode(c))
    dec = codec.decoder()
    for _ in codec.encode(c):
        fr = host.recv(2.0)
        assert fr is not None
        got = dec.feed(fr)
    assert got == c


@pytest.mark.parametrize("profile", ["can", "canfd"])
def test_virtual_back_to_back(links: Opener, profile: str) -> None:
    host = links("virtual:t_virtual", "host")
    target = links("virtual:t_virtual", "target")
    assert isinstance(host, Link) and host.fd
    assert host.poll() is None
    exchange(host, target, profile)
    assert host.stats.frames_tx == target.stats.frames_rx
    assert host.recv(0.001) is None  # no echo of own frames


def test_udp_plugin_one_process(links: Opener) -> None:
    a, b = free_udp_ports()
    host = links(f"udp:{a}:{b}", "host")
    target = links(f"udp:{b}:{a}@127.0.0.1", "target")
    exchange(host, target, "canfd")
    exchange(host, target, "can")
    assert host.stats.dropped == 0 and target.stats.frames_rx == 3


def test_udp_counts_gaps_duplicates_and_garbage(links: Opener) -> None:
    a, b = free_udp_ports()
    target = links(f"udp:{b}:{a}", "target")
    raw = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    raw.bind(("127.0.0.1", a))  # the configured peer, in session 7 (docs/protocol.md)
    session = SESSION.pack(7)
    try:
        raw.sendto(CONTROL.pack(0, MAGIC, HELLO, VERSION, 7), ("127.0.0.1", b))
        for seq in (0, 1, 1, 4, 3):
            body = pack_frame(0x200, bytes(7), 0, seq)
            raw.sendto(session + body + binascii.crc_hqx(body, 0xFFFF).to_bytes(2, "big"), ("127.0.0.1", b))
        raw.sendto(b"\x01\x02", ("127.0.0.1", b))
        raw.sendto(session + pack_frame(0x200, bytes(7), 0, 5)[:-1], ("127.0.0.1", b))
        got = [target.recv(0.5) for _ in range(4)]
    finally:
        raw.close()
    assert all(f is not None for f in got)
    assert target.recv(0.05) is None
    s = target.stats
    assert (s.duplicate, s.dropped, s.out_of_order, s.framing_errors) == (1, 2, 1, 2)


def test_udp_plugin_two_processes(links: Opener) -> None:
    a, b = free_udp_ports()
    with EchoPeer(f"udp:{b}:{a}"):
        host = links(f"udp:{a}:{b}", "host")
        frames = FrameCodec("can").encode(Command(7, (1, 2, 3), (1, 2, 3), 0, 0, 0, 0))
        host.send(frames)
        back = [host.recv(5.0) for _ in frames]
        host.send([Frame(STOP_ID, b"", False)])
    assert back == frames


def test_serial_pty_one_process(links: Opener, pty_pair: tuple[int, str]) -> None:
    master, name = pty_pair
    host = links(f"serial:{name},baudrate=3000000", "host")
    target = links(f"serial:fd:{master}", "target")
    exchange(host, target, "canfd")
    exchange(host, target, "can")


def test_serial_pty_garbage_and_crc_counted(links: Opener, pty_pair: tuple[int, str]) -> None:
    master, name = pty_pair
    host = links(f"serial:{name}", "host")
    good = encode_packet(pack_frame(0x700, bytes([0, 2, 1]), 0, 0))
    body = pack_frame(0x700, bytes([0, 2, 1]), 0, 1)
    bad = cobs_encode(body + (binascii.crc_hqx(body, 0xFFFF) ^ 0x8000).to_bytes(2, "big")) + b"\x00"
    os.write(master, b"\xde\xad\xbe\xef\x00" + bytes(bad) + good)
    fr = host.recv(2.0)
    assert fr == Frame(0x700, bytes([0, 2, 1]), False)
    assert host.stats.framing_errors == 1 and host.stats.crc_errors == 1


def test_serial_pty_two_processes(links: Opener, pty_pair: tuple[int, str]) -> None:
    master, name = pty_pair
    with EchoPeer(f"serial:fd:{master}", pass_fds=(master,)):
        host = links(f"serial:{name}", "host")
        frames = FrameCodec("canfd").encode(Measurement(9, 0.1, 0.2, -0.3, 0.5, 1.0, 24.0, 0))
        host.send(frames)
        back = host.recv(5.0)
        host.send([Frame(STOP_ID, b"", False)])
    assert back == frames[0]


def test_python_can_tools_work_over_plugins() -> None:
    a, b = free_udp_ports()
    with (
        can.Bus(interface="hiludp", channel=f"{a}:{b}") as x,
        can.Bus(interface="hiludp", channel=f"{b}:{a}") as y,
    ):
        x.send(can.Message(arbitration_id=0x1ABCDE, data=b"\x01\x02", is_extended_id=True))
        msg = y.recv(2.0)
        assert msg is not None and msg.arbitration_id == 0x1ABCDE and msg.is_extended_id
        assert bytes(msg.data) == b"\x01\x02"
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    with (
        can.Bus(interface="hilserial", channel=f"fd:{master}") as p,
        can.Bus(interface="hilserial", channel=f"fd:{slave}") as q,
    ):
        p.send(can.Message(arbitration_id=0x108, data=bytes(16), is_fd=True, is_extended_id=False))
        msg = q.recv(2.0)
        assert msg is not None and msg.is_fd and len(msg.data) == 16


def test_udp_multicast_via_python_can(links: Opener) -> None:
    try:
        host = links("udp_multicast:239.74.163.2,fd=true", "host")
        target = links("udp_multicast:239.74.163.2,fd=true", "target")
    except LinkError as exc:
        pytest.skip(f"multicast not routable here: {exc}")
    host.send([Frame(0x200, bytes(7), False)])
    fr = target.recv(1.0)
    if fr is None:
        pytest.skip("multicast datagrams not delivered on this host (no multicast route / loopback)")
    assert fr == Frame(0x200, bytes(7), False)


def test_socketcan_vcan(links: Opener) -> None:
    if not Path("/sys/class/net/vcan0").exists():
        pytest.skip("no SocketCAN interface vcan0 (kernel without vcan; `ip link add vcan0 type vcan`)")
    host = links("socketcan:vcan0,fd=true", "host")
    target = links("socketcan:vcan0,fd=true", "target")
    exchange(host, target, "canfd")


def test_spec_parsing_and_errors() -> None:
    ls = parse_spec("pcan:PCAN_USBBUS1,bitrate=1000000,fd=true,data_bitrate=5000000,name=x")
    assert (ls.kind, ls.channel) == ("pcan", "PCAN_USBBUS1")
    assert ls.options == {"bitrate": 1000000, "fd": True, "data_bitrate": 5000000, "name": "x"}
    assert parse_spec("serial:socket://localhost:5000").channel == "socket://localhost:5000"
    for bad, match in (
        ("", "empty"),
        (":x", "interface name"),
        ("udp:", "empty channel"),
        ("virtual,bitrate", "key=value"),
    ):
        with pytest.raises(LinkSpecError, match=match):
            parse_spec(bad)
    with pytest.raises(LinkSpecError, match="REMOTEPORT"):
        open_link("udp:1:0", "host")
    with pytest.raises(LinkSpecError, match="ports must be integers"):
        open_link("udp:a:b", "host")
    with pytest.raises(LinkError, match="nosuchbus"):
        open_link("nosuchbus:0", "host")
    with pytest.raises(LinkError, match="/dev/does-not-exist"):
        open_link("serial:/dev/does-not-exist", "host")
    with pytest.raises(LinkSpecError, match="role"):
        open_link("virtual", "plant")  # type: ignore[arg-type]


def test_send_rejects_invalid_frames(links: Opener) -> None:
    a, b = free_udp_ports()
    host = links(f"udp:{a}:{b}", "host")
    with pytest.raises(LinkError, match="0x100"):
        host.send([Frame(0x100, bytes(9), False)])
    with pytest.raises(LinkError, match="0x108"):
        host.send([Frame(0x108, bytes(13), True)])
    assert host.stats.send_errors == 2
    host.close()
    host.close()  # idempotent
