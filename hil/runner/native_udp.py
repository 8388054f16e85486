"""The native loop's UDP link (hil/native/loop_udp.c): the host's hiludp socket handed to C for the run.

Python opens the link and agrees the session (`UdpUnicastBus.wait_session`), configures the target and sends
the Setpoints; for the periods the C loop takes the same socket, session and link sequence numbers and hands
them back with its counters afterwards. Waiting for a Command busy-polls for `SPIN_NS`, then blocks.
"""

from __future__ import annotations

import socket
from collections.abc import Sequence
from typing import Any

from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links import Link
from pmsm_hil.protocol.links.stats import LinkStats
from pmsm_hil.protocol.links.udp_bus import UdpUnicastBus

#: busy-poll this long for a frame before blocking in ppoll [ns]: a lockstep round trip on an idle machine
#: is well inside it, and a loaded machine gets the core back instead of two spinning processes
SPIN_NS = 50_000
#: LinkStats counters the C link keeps (nl_udp_t fields of the same names)
COUNTERS = tuple(LinkStats.__slots__)


def udp_bus(link: Link) -> UdpUnicastBus | None:
    """The hiludp bus under `link`, or None."""
    bus = getattr(link, "bus", None)
    return bus if isinstance(bus, UdpUnicastBus) else None


def udp_handle(ffi: Any, bus: UdpUnicastBus, *, target_role: bool, spin_ns: int = SPIN_NS) -> Any:
    """A new nl_udp_t on `bus`'s socket, session, peer and link sequence numbers."""
    u = ffi.new("nl_udp_t *")
    ip, port = bus.peer
    u.fd = bus.fileno()
    u.session = bus.session
    u.peer_addr = int.from_bytes(socket.inet_aton(ip), "little")  # network byte order in memory
    u.peer_port = socket.htons(port)
    u.tx_seq, u.rx_last = bus.link_seq
    u.target_role = 1 if target_role else 0
    u.spin_ns = spin_ns
    return u


def udp_counters(u: Any) -> dict[str, int]:
    """The C link's LinkStats counters by name."""
    return {name: int(getattr(u, name)) for name in COUNTERS}


class NativeUdpLink:
    """The host's UDP link, usable by `TargetClient` between runs of the C loop and by the C loop itself
    (`handle`); `fd`: the host's frame profile is CAN FD."""

    def __init__(self, link: Link, bus: UdpUnicastBus, ffi: Any, lib: Any, fd: bool) -> None:
        self.link, self.bus = link, bus
        self.ffi, self.lib = ffi, lib
        self.fd = fd
        self.stats: LinkStats = link.stats
        #: errno of what the last run's real-time set-up was refused: mlockall, SCHED_FIFO, CPU affinity (0: ok)
        self.rt_errnos: tuple[int, int, int] = (0, 0, 0)
        self.handle: Any = None

    def attach(self, c: Any, lockstep_timeout_s: float) -> None:
        """Give the loop's nl_config_t `c` the socket as it is now."""
        self.handle = udp_handle(self.ffi, self.bus, target_role=False)
        c.udp = self.handle
        c.lockstep_timeout_ns = int(lockstep_timeout_s * 1e9)

    def detach(self) -> None:
        """After the run: the C link's counters into `stats`, its link sequence numbers back to the bus."""
        u = self.handle
        if u is None:
            return
        for name, value in udp_counters(u).items():
            setattr(self.stats, name, getattr(self.stats, name) + value)
        self.bus.resume_link_seq(int(u.tx_seq), int(u.rx_last))
        self.handle = None

    def send(self, frames: Sequence[Frame]) -> None:
        """As `Link.send` (Python, between runs of the C loop)."""
        self.link.send(frames)

    def poll(self) -> Frame | None:
        """As `Link.poll`."""
        return self.link.poll()

    def recv(self, timeout_s: float) -> Frame | None:
        """As `Link.recv`."""
        return self.link.recv(timeout_s)

    def close(self) -> None:
        """Close the link (idempotent)."""
        self.link.close()
