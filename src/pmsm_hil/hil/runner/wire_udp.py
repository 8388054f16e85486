"""The native loop's UDP link (src/pmsm_hil/hil/runner/c/links/loop_udp.c): the host's hiludp bus, a C link whose own
state (socket, agreed session, link sequence numbers, authentication) the loop drives (`UDP_WIRE`, see wire.py).

Python opens the link and agrees the session (`HilUdpBus.wait_session`); the native target adopts the session of
the host's HELLO in C (target role).
"""

from __future__ import annotations

from pmsm_hil.hil.runner.wire import Wire
from pmsm_hil.protocol.links import Link
from pmsm_hil.protocol.links.wire_bus import HilUdpBus


def udp_bus(link: Link) -> HilUdpBus | None:
    """The hiludp bus under `link`, or None."""
    bus = getattr(link, "bus", None)
    return bus if isinstance(bus, HilUdpBus) else None


UDP_WIRE = Wire("nl_udp_t", "nl_udp_link", udp_bus)
