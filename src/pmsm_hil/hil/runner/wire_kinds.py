"""The link kinds the native loop drives from C (by SPEC kind; src/pmsm_hil/hil/runner/c/links/nl_link.h): a new one is
a C file filling an nl_link_t and a `Wire` here."""

from __future__ import annotations

from pmsm_hil.hil.runner.wire import Wire
from pmsm_hil.hil.runner.wire_serial import SERIAL_WIRE
from pmsm_hil.hil.runner.wire_socketcan import SOCKETCAN_WIRE
from pmsm_hil.hil.runner.wire_udp import UDP_WIRE

NATIVE_WIRES: dict[str, Wire] = {"udp": UDP_WIRE, "serial": SERIAL_WIRE, "socketcan": SOCKETCAN_WIRE}
