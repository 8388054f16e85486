"""The native loop's UDP link (src/pmsm_hil/hil/runner/c/links/loop_udp.c): the host's hiludp socket, its agreed session
and link sequence numbers handed to C (`UDP_WIRE`, see wire.py).

Python opens the link and agrees the session (`UdpUnicastBus.wait_session`); the native target adopts the
session of the host's HELLO in C (target role).
"""

from __future__ import annotations

import socket
from typing import Any

from pmsm_hil.hil.runner.wire import NativeWireLink, Wire
from pmsm_hil.protocol.links import Link
from pmsm_hil.protocol.links.udp_bus import UdpUnicastBus


def udp_bus(link: Link) -> UdpUnicastBus | None:
    """The hiludp bus under `link`, or None."""
    bus = getattr(link, "bus", None)
    return bus if isinstance(bus, UdpUnicastBus) else None


def _fill(ffi: Any, u: Any, bus: UdpUnicastBus, target_role: bool) -> None:
    """nl_udp_t `u` on `bus`'s socket, session, peer and link sequence numbers."""
    ip, port = bus.peer
    u.fd = bus.fileno()
    u.session = bus.session
    u.peer_addr = int.from_bytes(socket.inet_aton(ip), "little")  # network byte order in memory
    u.peer_port = socket.htons(port)
    u.tx_seq, u.rx_last = bus.link_seq
    u.target_role = 1 if target_role else 0
    u.nonce = bus.nonce


def _hand_back(ffi: Any, u: Any, bus: UdpUnicastBus) -> None:
    bus.resume_link_seq(int(u.tx_seq), int(u.rx_last))


UDP_WIRE = Wire("nl_udp_t", "nl_udp_link", udp_bus, _fill, _hand_back)

#: every link to another process is a NativeWireLink now (the name loop.py still uses)
NativeUdpLink = NativeWireLink
