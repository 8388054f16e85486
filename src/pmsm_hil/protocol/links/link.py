"""Links: move frames between host and target over any python-can bus or our UDP / serial plugins.

`open_link(spec, role)` parses a SPEC string (docs/protocol.md, "Link specs"):
    virtual[:CHANNEL]                 python-can virtual bus, in-process (default channel "pmsm_hil")
    can[,opt=val...]                  python-can config file + environment (can.util.load_config)
    udp[:LOCALPORT:REMOTEPORT[@HOST]] UDP unicast plugin (hiludp); ports default by role
    serial:PORT_OR_URL[,baudrate=N]   COBS serial plugin (hilserial); PORT may be fd:N
    NAME:CHANNEL[,opt=val...]         any python-can interface (socketcan:can0, pcan:PCAN_USBBUS1,
                                      kvaser:0, slcan:/dev/ttyACM0, gs_usb:0, udp_multicast:239.74.163.2)
Options are passed to can.Bus (bitrate=1000000,fd=true,data_bitrate=5000000, ...).
"""

from __future__ import annotations

import queue
import sys
import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

from pmsm_hil.protocol.errors import LinkError, LinkSpecError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links.kinds import link_kind
from pmsm_hil.protocol.links.shared_bus import SHARED_OPTION, is_shared_bus
from pmsm_hil.protocol.links.spec import Role, parse_spec, redact_spec
from pmsm_hil.protocol.links.stats import LinkStats
from pmsm_hil.protocol.links.wire_core import WireEnd, WireInitError

if TYPE_CHECKING:  # python-can is imported where a python-can bus is opened or asked for, not for the C wires
    import can
    from can.interfaces.virtual import VirtualBus

_perf = time.perf_counter
_TRUE = ("true", "1", "yes", "on")


@runtime_checkable
class Link(Protocol):
    """A bidirectional frame pipe; `poll` and `recv` busy-poll (no sleeps, no blocking syscalls)."""

    stats: LinkStats
    fd: bool

    def send(self, frames: Sequence[Frame]) -> None:
        """Send frames in order; raises LinkError if the transport refuses one."""
        ...

    def poll(self) -> Frame | None:
        """The next received frame, or None at once."""
        ...

    def recv(self, timeout_s: float) -> Frame | None:
        """The next received frame within `timeout_s` seconds, or None after it."""
        ...

    def close(self) -> None:
        """Release the transport (idempotent)."""
        ...


def poll_until(poll: Callable[[], Frame | None], timeout_s: float) -> Frame | None:
    """Call `poll` until it returns a frame or `timeout_s` seconds of wall time have passed (busy-polling)."""
    fr = poll()
    if fr is not None:
        return fr
    deadline = _perf() + timeout_s
    while _perf() < deadline:
        fr = poll()
        if fr is not None:
            return fr
    return None


class BusLink:
    """Link over a python-can bus, or over a C wire end (hiludp / hilserial: wire_core.py) through its fast path with
    its C counters as `stats`, without python-can (its python-can bus made on first use of `bus`)."""

    def __init__(self, bus: can.BusABC | WireEnd, description: str) -> None:
        #: what the link was opened on, as it is (a C wire end or a python-can bus): `link_end` reads it
        self.end: Any = bus
        self.description = description
        self._fast: WireEnd | None = bus if isinstance(bus, WireEnd) else None
        self.stats: LinkStats = self._fast.link_stats if self._fast is not None else LinkStats()
        self._closed = False
        #: other nodes may share this bus (src/pmsm_hil/protocol/links/shared_bus.py): frames that cannot be the
        #: target's are bus traffic, not findings; set by open_link from the SPEC
        self.shared = False
        self._virtual: VirtualBus | None = None
        self._can_error: type[Exception] = LinkError  # python-can's CanError on a python-can bus
        if self._fast is not None:
            self.fd = self._fast.fd
            return
        import can
        from can import CanProtocol
        from can.interfaces.virtual import VirtualBus

        self._can_error = can.CanError
        self._message = can.Message
        protocol = getattr(bus, "protocol", None)
        self.fd = protocol in (CanProtocol.CAN_FD, CanProtocol.CAN_FD_NON_ISO) or bool(getattr(bus, "fd", False))
        # python-can's virtual bus deep-copies every Message per receiver (~10 µs); in-process we hand each
        # receiver queue its own freshly built Message instead: same semantics, a fraction of the cost.
        self._virtual = bus if type(bus) is VirtualBus else None

    @property
    def bus(self) -> can.BusABC:
        """The python-can bus of the link: a C wire end becomes its python-can bus (`HilUdpBus`, `HilSerialBus`:
        the same end, python-can imported now)."""
        if self._fast is not None and self.end is self._fast:
            from pmsm_hil.protocol.links.wire_bus import python_can_face

            self.end = python_can_face(self._fast)
        bus: can.BusABC = self.end
        return bus

    def _send_virtual(self, bus: VirtualBus, fr: Frame) -> None:
        now = time.time()
        for q in bus.channel:
            if q is bus.queue and not bus.receive_own_messages:
                continue
            q.put_nowait(self._message(timestamp=now, arbitration_id=fr.arbitration_id, data=fr.data,
                                      is_fd=fr.is_fd, bitrate_switch=fr.is_fd, is_extended_id=False,
                                      channel=bus.channel_id, is_rx=q is not bus.queue))
        self.stats.frames_tx += 1

    def send(self, frames: Sequence[Frame]) -> None:
        """Send frames in order; raises LinkError (naming the frame id) if the transport refuses one."""
        fast = self._fast
        for fr in frames:
            try:
                if fast is not None:
                    fast.send_frame(fr.arbitration_id, fr.data, fr.is_fd)
                elif self._virtual is not None:
                    self._send_virtual(self._virtual, fr)
                else:
                    self._send_message(fr)
            except (self._can_error, LinkError, ValueError, TypeError) as exc:
                if fast is None:
                    self.stats.send_errors += 1
                raise LinkError(f"{self.description}: cannot send frame 0x{fr.arbitration_id:03X}: {exc}") from exc

    def _send_message(self, fr: Frame) -> None:
        self.end.send(self._message(arbitration_id=fr.arbitration_id, data=fr.data, is_fd=fr.is_fd,
                                  bitrate_switch=fr.is_fd, is_extended_id=False))
        self.stats.frames_tx += 1

    def _next_message(self) -> can.Message | None:
        """The next raw message, or None at once (virtual: straight from its queue, no BusABC layers)."""
        virtual = self._virtual
        if virtual is not None:
            if not virtual.queue.queue:  # empty: skip the lock and the Empty exception (busy polling)
                return None
            try:
                msg: can.Message = virtual.queue.get_nowait()
            except queue.Empty:
                return None
            return msg
        try:
            received: can.Message | None = self.end.recv(0.0)
        except self._can_error:
            self.stats.framing_errors += 1
            return None
        return received

    def poll(self) -> Frame | None:
        """The next received 11-bit data frame, or None at once."""
        if self._fast is not None:
            return self._fast.poll_frame()
        while True:
            msg = self._next_message()
            if msg is None:
                return None
            if msg.is_error_frame or msg.is_remote_frame or msg.is_extended_id:
                self.stats.ignored += 1
                continue
            self.stats.frames_rx += 1
            return Frame(msg.arbitration_id, bytes(msg.data), msg.is_fd)

    def recv(self, timeout_s: float) -> Frame | None:
        """Wait up to `timeout_s` seconds: on the hiludp / hilserial buses blocked in their receive (a host that
        spins while it waits takes the CPU from a peer on the same machine), else busy-polling."""
        if self._fast is not None:
            return self._fast.next_frame(time.monotonic_ns() + max(0, int(timeout_s * 1e9)))
        return poll_until(self.poll, timeout_s)

    def close(self) -> None:
        """Shut the bus down (idempotent)."""
        if not self._closed:
            self._closed = True
            self.end.shutdown()

    def __enter__(self) -> BusLink:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _open_errors() -> tuple[type[Exception], ...]:
    """What opening a bus may raise: python-can's errors where python-can is imported (else no bus raised one)."""
    base: tuple[type[Exception], ...] = (OSError, ValueError, TypeError, ImportError, KeyError)
    can = sys.modules.get("can")
    return base if can is None else (can.CanError, can.CanInterfaceNotImplementedError, *base)


def open_link(spec: str = "virtual", role: Role = "host") -> BusLink:
    """Open a link end from a SPEC string; raises LinkSpecError / LinkError naming the spec."""
    if role not in ("host", "target"):
        raise LinkSpecError(f"role={role!r} (expected 'host' or 'target')")
    ls = parse_spec(spec)
    shared = ls.options.pop(SHARED_OPTION, None)  # how the host reads the bus (shared_bus.py): not python-can's
    try:
        bus, description = link_kind(ls).open_bus(ls, role)
    except LinkError as exc:
        if not isinstance(exc, WireInitError):  # a C wire end's refusal is worded as python-can's is
            raise
        raise LinkError(f"cannot open link {redact_spec(spec)!r}: {exc}") from exc
    except _open_errors() as exc:
        raise LinkError(f"cannot open link {redact_spec(spec)!r}: {exc}") from exc
    link = BusLink(bus, description)
    link.shared = is_shared_bus(spec) if shared is None else shared is True or str(shared).lower() in _TRUE
    return link
