"""python-can's own conformance tests against the `hiludp` and `hilserial` interfaces: `Back2BackTestCase` and
`TestThreadSafeBus` of python-can's test/back2back_test.py (vendored verbatim in tests/third_party/python_can, with
the version it comes from), run unchanged on two ends of one link. Skipped: what python-can skips itself (its own
skip marks stay), and what a point-to-point link cannot do, each with its reason below. Every test is bounded in
time (pytest-timeout): a receive that waits for a lost frame fails instead of hanging."""

from __future__ import annotations

import os
import threading
import tty
from typing import Any

import can
import pytest

from pmsm_hil.protocol.links.wire_bus import HilSerialBus, HilUdpBus, free_udp_ports
from tests.third_party.python_can import back2back_test as b2b

pytestmark = pytest.mark.timeout(120)

#: a point-to-point link has exactly two ends: a third bus on one end's channel cannot join it
POINT_TO_POINT = ("a point-to-point link has two ends: a third bus (bus3, receive_own_messages) on bus2's channel "
                  "cannot join it")


class _UdpEnds:
    """Two hiludp ends on free loopback ports, each the other's peer."""

    INTERFACE_1 = INTERFACE_2 = "hiludp"

    def _channels(self) -> None:
        a, b = free_udp_ports(2)
        self.CHANNEL_1, self.CHANNEL_2 = f"{a}:{b}", f"{b}:{a}"


class _SerialEnds:
    """Two hilserial ends on the two sides of a pty in raw mode (each bus owns its descriptor)."""

    INTERFACE_1 = INTERFACE_2 = "hilserial"

    def _channels(self) -> None:
        master, slave = os.openpty()
        tty.setraw(master)
        tty.setraw(slave)
        self.CHANNEL_1, self.CHANNEL_2 = f"fd:{master}", f"fd:{slave}"


class _PointToPoint:
    """What differs on a point-to-point link from python-can's shared virtual channel."""

    CHANNEL_1: str
    CHANNEL_2: str
    bus2: Any

    def _channels(self) -> None:
        raise NotImplementedError

    def setUp(self) -> None:
        self._channels()
        super().setUp()  # type: ignore[misc]

    def test_unique_message_instances(self) -> None:
        pytest.skip(POINT_TO_POINT)

    @pytest.mark.timing
    def test_send_periodic_duration(self) -> None:
        """python-can's test unchanged, in the `timing` step: python-can's cyclic sender fixes its end time before
        its thread starts, so on a loaded machine a thread that starts over 10 ms late sends nothing (seen with the
        virtual bus alike) and the test fails on an empty list, whatever the bus."""
        super().test_send_periodic_duration()  # type: ignore[misc]


class _ThreadSafe(_PointToPoint):
    """The thread-safe tests compare each received Message with the one sent, channel included: on a shared channel
    both ends have one name, on a point-to-point link the received frame carries the receiving end's channel, so the
    sent Message is built with that one (the frames themselves are unchanged)."""

    def setUp(self) -> None:
        super().setUp()
        self.CHANNEL_1 = self.bus2.channel_name if hasattr(self.bus2, "channel_name") else \
            self.bus2.__wrapped__.channel_name

    @pytest.mark.timeout(120)
    def test_concurrent_writes(self) -> None:
        super().test_concurrent_writes()  # type: ignore[misc]

    @pytest.mark.timeout(120)
    def test_filtered_bus(self) -> None:
        super().test_filtered_bus()  # type: ignore[misc]


class TestBack2BackUdp(_UdpEnds, _PointToPoint, b2b.Back2BackTestCase):
    """python-can's Back2BackTestCase on two hiludp ends."""


class TestBack2BackSerial(_SerialEnds, _PointToPoint, b2b.Back2BackTestCase):
    """python-can's Back2BackTestCase on two hilserial ends."""


class TestThreadSafeUdp(_UdpEnds, _ThreadSafe, b2b.TestThreadSafeBus):
    """python-can's TestThreadSafeBus on two hiludp ends."""


class TestThreadSafeSerial(_SerialEnds, _ThreadSafe, b2b.TestThreadSafeBus):
    """python-can's TestThreadSafeBus on two hilserial ends."""


def _pair_udp() -> tuple[HilUdpBus, HilUdpBus]:
    a, b = free_udp_ports(2)
    return HilUdpBus(f"{a}:{b}"), HilUdpBus(f"{b}:{a}")


def test_the_plugins_are_the_c_wire_buses() -> None:
    """`can.Bus(interface="hiludp" / "hilserial")` opens the C-backed buses."""
    a, b = free_udp_ports(2)
    with can.Bus(interface="hiludp", channel=f"{a}:{b}") as bus:
        assert isinstance(bus, HilUdpBus)
    master, slave = os.openpty()
    os.close(slave)
    with can.Bus(interface="hilserial", channel=f"fd:{master}") as bus:
        assert isinstance(bus, HilSerialBus)


@pytest.mark.parametrize("msg", [
    can.Message(arbitration_id=0x123, is_fd=True, bitrate_switch=False, data=bytes(range(12))),
    can.Message(arbitration_id=0x123, is_fd=True, bitrate_switch=True, error_state_indicator=True, data=b"\1" * 64),
    can.Message(arbitration_id=0x1ABCDEF, is_extended_id=True, is_remote_frame=True, dlc=4),
    can.Message(arbitration_id=0x7FF, is_remote_frame=True, dlc=0),
    can.Message(arbitration_id=0x55, data=b"\xaa" * 8),
], ids=["fd-no-brs", "fd-brs-esi", "rtr-dlc4-ext", "rtr-dlc0", "classic"])
def test_every_flag_and_the_remote_dlc_cross_the_wire(msg: can.Message) -> None:
    x, y = _pair_udp()
    with x, y:
        x.send(msg)
        got = y.recv(5.0)
    assert got is not None
    assert got.equals(msg, timestamp_delta=None, check_channel=False), (got, msg)


def test_receive_own_messages_is_honoured() -> None:
    a, b = free_udp_ports(2)
    with HilUdpBus(f"{a}:{b}", receive_own_messages=True) as x, HilUdpBus(f"{b}:{a}") as y:
        x.send(can.Message(arbitration_id=0x10, data=b"\1"))
        own = x.recv(1.0)
        assert own is not None and not own.is_rx and own.arbitration_id == 0x10
        assert y.recv(1.0) is not None
        y.send(can.Message(arbitration_id=0x11))
        assert y.recv(0.05) is None  # off by default
        got = x.recv(1.0)
        assert got is not None and got.is_rx and got.arbitration_id == 0x11


def test_a_1000_frame_burst_is_kept_or_counted() -> None:
    """1000 frames sent before the receiver reads one: the receive buffer (4 MiB asked) keeps them all; what the
    kernel drops (the system's default buffer) is counted by the bus (SO_RXQ_OVFL, /proc/net/udp), so received +
    kernel_dropped == sent either way (the 8-bit link sequence number cannot count a gap of hundreds)."""
    for rcvbuf in (4 << 20, 0):  # asked for, and the system default
        a, b = free_udp_ports(2)
        with HilUdpBus(f"{a}:{b}") as x, HilUdpBus(f"{b}:{a}", rcvbuf=rcvbuf) as y:
            for i in range(1000):
                x.send(can.Message(arbitration_id=0x100 + i % 16, data=i.to_bytes(2, "little")))
            got = 0
            while y.recv(0.5) is not None:
                got += 1
            assert got + y.kernel_dropped() == 1000, (rcvbuf, got, y.kernel_dropped(), y.rcvbuf)
            x.send(can.Message(arbitration_id=0x7FF))  # a frame after the burst carries the SO_RXQ_OVFL count
            assert y.recv(5.0) is not None
            if rcvbuf:
                assert got == 1000, (y.rcvbuf, y.kernel_dropped())
            else:
                assert y._state.kernel_drops == 1000 - got  # SO_RXQ_OVFL of the frame after the burst


@pytest.mark.parametrize("suffix", [".log", ".asc", ".csv"])
def test_the_channel_round_trips_through_python_cans_loggers(tmp_path: Any, suffix: str) -> None:
    """A received frame written by can.Logger is read back by can.LogReader (a channel with spaces broke .log)."""
    x, y = _pair_udp()
    with x, y:
        x.send(can.Message(arbitration_id=0x42, data=b"\1\2\3"))
        got = y.recv(5.0)
    assert got is not None and " " not in str(got.channel)
    path = tmp_path / f"capture{suffix}"
    with can.Logger(path) as logger:
        logger(got)
    back = list(can.LogReader(path))
    assert len(back) == 1 and back[0].arbitration_id == 0x42 and bytes(back[0].data) == b"\1\2\3"
    if suffix == ".log":
        assert back[0].channel == got.channel


def test_frames_the_bus_cannot_carry_are_refused_and_counted() -> None:
    a, b = free_udp_ports(2)
    with HilUdpBus(f"{a}:{b}", fd=False) as x, HilUdpBus(f"{b}:{a}") as y:
        with pytest.raises(can.CanOperationError, match="FD frame on a classic bus"):
            x.send(can.Message(arbitration_id=0x10, is_fd=True, data=bytes(12)))
        with pytest.raises(can.CanOperationError, match="cannot carry"):
            y.send(can.Message(arbitration_id=0x10, is_fd=True, data=bytes(13)))  # no FD length
        with pytest.raises(can.CanOperationError, match="error frames"):
            y.send(can.Message(is_error_frame=True))
        assert x.link_stats.send_errors == y.link_stats.send_errors == 1


def test_a_shutdown_ends_a_receive_waiting_in_another_thread() -> None:
    x, y = _pair_udp()
    ended: list[BaseException] = []

    def wait() -> None:
        try:
            x.recv()  # no timeout
        except can.CanOperationError as exc:
            ended.append(exc)

    with y:
        waiter = threading.Thread(target=wait)
        waiter.start()
        x.shutdown()
        waiter.join(10.0)
    assert not waiter.is_alive() and "shut down" in str(ended[0])
    with pytest.raises(can.CanOperationError, match="shut down"):
        x.send(can.Message())


def test_bad_channels_are_refused_naming_them() -> None:
    with pytest.raises(can.CanInitializationError, match="LOCALPORT:REMOTEPORT"):
        HilUdpBus("47310")
    with pytest.raises(can.CanInitializationError, match="loop://"):
        HilSerialBus("loop://")


def test_authenticated_ends_agree_and_a_foreign_key_is_refused() -> None:
    """With auth_key the C handshake agrees a session with the peer's nonce before the first frame (both ways, and
    over a pty); a peer with another key refuses the HELLO, and the sender says so instead of waiting."""
    key = bytes(range(32))
    a, b = free_udp_ports(2)
    with HilUdpBus(f"{a}:{b}", auth_key=key) as x, HilUdpBus(f"{b}:{a}", auth_key=key, auth_role="target") as y:
        received: list[can.Message | None] = []
        peer = threading.Thread(target=lambda: received.append(y.recv(5.0)))  # it answers the HELLO as it waits
        peer.start()
        x.send(can.Message(arbitration_id=0x21, data=b"\1\2"))
        peer.join()
        assert received[0] is not None and bytes(received[0].data) == b"\1\2"
        y.send(can.Message(arbitration_id=0x22, data=b"\3"))
        got = x.recv(5.0)
        assert got is not None and bytes(got.data) == b"\3"
        assert x.session == y.session != 0 and x.link_stats.auth_failed == y.link_stats.auth_failed == 0
    a, b = free_udp_ports(2)
    with HilUdpBus(f"{a}:{b}", auth_key=key) as x, \
            HilUdpBus(f"{b}:{a}", auth_key=bytes(32), auth_role="target") as y:
        peer = threading.Thread(target=lambda: y.recv(3.0))
        peer.start()
        with pytest.raises(can.CanOperationError, match="refused our HELLO"):
            x.wait_session(5.0)
        peer.join()
        assert y.link_stats.auth_failed >= 1
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    with HilSerialBus(f"fd:{master}", auth_key=key) as p, \
            HilSerialBus(f"fd:{slave}", auth_key=key, auth_role="target") as q:
        p.send(can.Message(arbitration_id=0x23, data=b"\4"))
        got = q.recv(5.0)
        assert got is not None and bytes(got.data) == b"\4" and q.link_stats.auth_failed == 0
