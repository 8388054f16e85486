"""The native loop's serial link (src/pmsm_hil/hil/runner/c/links/loop_serial.c): the host's hilserial bus, a C link
whose own state (port, COBS/CRC framing, link sequence numbers, a packet half received, authentication) the loop
drives (`SERIAL_WIRE`, see wire.py)."""

from __future__ import annotations

from pmsm_hil.hil.runner.wire import Wire
from pmsm_hil.protocol.links import Link
from pmsm_hil.protocol.links.wire_core import SerialEnd, link_end


def serial_bus(link: Link) -> SerialEnd | None:
    """The hilserial end (or bus) under `link`, or None."""
    end = link_end(link)
    return end if isinstance(end, SerialEnd) else None


SERIAL_WIRE = Wire("nl_serial_t", "nl_serial_link", serial_bus)
