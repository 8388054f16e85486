"""The native loop's UDP link (src/pmsm_hil/hil/runner/c/links/loop_udp.c): the host's hiludp bus, a C link whose own
state (socket, agreed session, link sequence numbers, authentication) the loop drives (`UDP_WIRE`, see wire.py).

Python opens the link and agrees the session (`UdpEnd.wait_session`); the native target adopts the session of
the host's HELLO in C (target role).
"""

from __future__ import annotations

from pmsm_hil.hil.runner.wire import Wire
from pmsm_hil.protocol.links import Link
from pmsm_hil.protocol.links.wire_core import UdpEnd, link_end


def udp_bus(link: Link) -> UdpEnd | None:
    """The hiludp end (or bus) under `link`, or None."""
    end = link_end(link)
    return end if isinstance(end, UdpEnd) else None


UDP_WIRE = Wire("nl_udp_t", "nl_udp_link", udp_bus)
