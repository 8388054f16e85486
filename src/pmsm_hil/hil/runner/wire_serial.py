"""The native loop's serial link (src/pmsm_hil/hil/runner/c/links/loop_serial.c): the host's hilserial port (a tty
pyserial set to raw mode, or a pty master) handed to C with its link sequence numbers and a packet half received
(`SERIAL_WIRE`, see wire.py). The frames, COBS/CRC framing and counters are the Python link's (serial_bus.py)."""

from __future__ import annotations

from typing import Any

from pmsm_hil.hil.runner.wire import Wire
from pmsm_hil.protocol.links import Link
from pmsm_hil.protocol.links.serial_bus import CobsSerialBus

#: a port that takes no output for this long fails the frame (a send error) instead of blocking the run [ns]
WRITE_TIMEOUT_NS = 1_000_000_000


def serial_bus(link: Link) -> CobsSerialBus | None:
    """The hilserial bus under `link` when it has a descriptor C can read (not a socket:// URL), or None."""
    bus = getattr(link, "bus", None)
    if not isinstance(bus, CobsSerialBus):
        return None
    try:
        bus.fileno()
    except NotImplementedError:
        return None
    return bus


def _fill(ffi: Any, s: Any, bus: CobsSerialBus, target_role: bool) -> None:
    """nl_serial_t `s` on `bus`'s descriptor, link sequence numbers and deframer state."""
    s.fd = bus.fileno()
    s.fd_frames = 1 if bus.fd else 0
    s.framer.tx_seq, s.rx_last = bus.link_seq
    s.write_timeout_ns = WRITE_TIMEOUT_NS
    pending, discarding = bus.deframer.pending
    ffi.memmove(s.pkt, pending, len(pending))
    s.pkt_n, s.discarding = len(pending), 1 if discarding else 0


def _hand_back(ffi: Any, s: Any, bus: CobsSerialBus) -> None:
    """The link sequence numbers, the packet half received and the bytes read but not fed back to `bus`."""
    bus.resume_link_seq(int(s.framer.tx_seq), int(s.rx_last))
    pending = b"" if s.discarding else ffi.buffer(s.pkt, int(s.pkt_n))[:]
    bus.deframer.resume(pending, bool(s.discarding))
    unread = ffi.buffer(s.rx, int(s.rx_n))[int(s.rx_at):]
    if unread:
        bus.deframer.feed(unread)


SERIAL_WIRE = Wire("nl_serial_t", "nl_serial_link", serial_bus, _fill, _hand_back)
