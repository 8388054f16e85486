"""python-can interfaces `hiludp` and `hilserial` on the C wire links.

The framing, CRC, link sequence numbers, UDP session handshake and frame authentication of both wires are the C
links of the period loop (src/pmsm_hil/hil/runner/c/links: loop_udp.c, loop_serial.c, nl_link.c), compiled once
more into the extension `_wire_native` (_build_wire.py): each wire is written once, in C. This module is only the
python-can face of the ends of wire_core.py (which a run opens without python-can), modelled on python-can's own
buses (`BusABC._recv_internal`, `VirtualBus`): Messages in and out, timeouts, `receive_own_messages`, and filters
(by BusABC).

What a frame keeps on these wires: arbitration id (11 or 29 bits), data, FD, BRS, ESI, a remote frame with its DLC
(docs/protocol.md). Error frames are not carried. `Message.channel` of a received frame is the bus's channel string
(whitespace replaced by "_", so python-can's loggers write a log their readers read back).

- hiludp, channel "LOCALPORT:REMOTEPORT[@HOST]" (HOST default 127.0.0.1), e.g.
  `can.Bus(interface="hiludp", channel="47310:47311")`. The receive buffer is `rcvbuf` bytes (default 4 MiB: a
  burst of 1000 frames is kept; forced past the system limit where the process may); datagrams the kernel drops
  anyway are counted (`kernel_dropped()`, SO_RXQ_OVFL as python-can's SocketCAN bus reads it).
- hilserial, channel: a serial device (/dev/ttyACM0), a pyserial URL whose port has a descriptor, or "fd:N" for an
  open descriptor the bus then owns (a pty end from os.openpty(), in raw mode).
Both take `fd` (CAN FD frames allowed, default True), `receive_own_messages` and `auth_key` / `auth_role`
(authenticated frames, docs/protocol.md "Authenticated frames").
"""

from __future__ import annotations

import time
from typing import Any

import can
from can import CanProtocol

from pmsm_hil.protocol.links._wire_native import ffi, lib
from pmsm_hil.protocol.links.wire_core import (
    DEFAULT_RCVBUF,
    NEVER_NS,
    WAIT_SLICE_S,
    Queued,
    SerialEnd,
    UdpEnd,
    UdpSessionError,
    WireEnd,
    WireError,
    WireInitError,
    WireLinkStats,
    deadline_ns,
    free_udp_ports,
    link_socket_drops,
    parse_udp_channel,
    udp_socket_drops,
)


class CanWireError(WireError, can.CanOperationError):
    """A wire end's send or receive failed (python-can's CanOperationError, and a LinkError)."""


class CanWireInitError(WireInitError, can.CanInitializationError):
    """A wire end cannot be opened (python-can's CanInitializationError, and a LinkError)."""


class CanUdpSessionError(UdpSessionError, can.CanOperationError):
    """No UDP session was agreed (python-can's CanOperationError, and wire_core's UdpSessionError)."""


def _flags(msg: can.Message) -> int:
    """The wire flags of a Message."""
    return ((lib.NL_WIRE_FD if msg.is_fd else 0) | (lib.NL_WIRE_BRS if msg.bitrate_switch else 0)
            | (lib.NL_WIRE_ESI if msg.error_state_indicator else 0)
            | (lib.NL_WIRE_EXTENDED if msg.is_extended_id else 0)
            | (lib.NL_WIRE_REMOTE if msg.is_remote_frame else 0))


class WireBus(WireEnd, can.BusABC):
    """The python-can bus on one C wire link: a `WireEnd` with python-can's Messages, filters and errors."""

    _op_error = CanWireError
    _init_error = CanWireInitError
    _session_error = CanUdpSessionError
    __del__ = can.BusABC.__del__

    def _opened(self, channel: Any, kwargs: dict[str, Any]) -> None:
        super()._opened(channel, kwargs)
        self._python_can_state()

    def _python_can_state(self) -> None:
        """python-can's bus state: the protocol, the filters of the options it was opened with, open."""
        self._can_protocol = CanProtocol.CAN_FD if self.fd else CanProtocol.CAN_20
        can.BusABC.__init__(self, channel=self.channel, **self._face_kwargs)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Send `msg`; CanOperationError for a frame the wire cannot carry or an I/O error."""
        self._check_open()
        if msg.is_error_frame:
            raise CanWireError(f"{self.channel_info}: error frames are not carried")
        data = b"" if msg.is_remote_frame else bytes(msg.data)
        if msg.is_fd and not self.fd:
            self._state.stats.send_errors += 1
            raise CanWireError(f"{self.channel_info}: an FD frame on a classic bus (fd=False)")
        if len(data) > 64 or (msg.is_remote_frame and not 0 <= msg.dlc <= 8):
            raise CanWireError(f"{self.channel_info}: a frame of {len(data) or msg.dlc} bytes")
        m = ffi.new("nl_wire_frame_t *")
        m.id = msg.arbitration_id
        m.flags = _flags(msg)
        m.len = msg.dlc if msg.is_remote_frame else len(data)
        ffi.memmove(m.data, data, len(data))
        self._sent(self._send_wire(m, deadline_ns(1.0 if timeout is None else timeout)),
                   f"the wire cannot carry this frame (id 0x{msg.arbitration_id:X}, "
                   f"{'FD' if msg.is_fd else 'classic'}, {len(data)} bytes)")
        if self.receive_own_messages:
            self._queued.append(Queued(msg.arbitration_id, int(m.flags), msg.dlc, data or None, time.time(), False))

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        self._check_open()
        deadline = NEVER_NS if timeout is None else deadline_ns(timeout)
        m = ffi.new("nl_wire_frame_t *")
        while not self._queued:
            now = lib.nl_now_ns()
            got = self._recv_wire(m, min(deadline, now + int(WAIT_SLICE_S * 1e9)))
            if got == 1:
                return self._message(self._received(m)), False
            if got < 0:
                raise CanWireError(f"{self.channel_info}: the peer closed the link")
            self._check_open()
            if lib.nl_now_ns() >= deadline:
                return None, False
        return self._message(self._queued.popleft()), False

    def _message(self, q: Queued) -> can.Message:
        flags = q.flags
        return can.Message(
            timestamp=q.timestamp, arbitration_id=q.arbitration_id, is_extended_id=bool(flags & lib.NL_WIRE_EXTENDED),
            is_remote_frame=bool(flags & lib.NL_WIRE_REMOTE), is_fd=bool(flags & lib.NL_WIRE_FD),
            bitrate_switch=bool(flags & lib.NL_WIRE_BRS), error_state_indicator=bool(flags & lib.NL_WIRE_ESI),
            dlc=q.dlc, data=q.data, channel=self.channel_name, is_rx=q.is_rx)

    def shutdown(self) -> None:
        """Close the link (python-can API; idempotent)."""
        if self._is_shutdown:
            return
        can.BusABC.shutdown(self)
        self._close()


class HilUdpBus(UdpEnd, WireBus):
    """Point-to-point UDP bus (python-can interface `hiludp`) with a per-session handshake, on loop_udp.c."""


class HilSerialBus(SerialEnd, WireBus):
    """Frames over a serial line (UART, USB CDC, pty) with COBS framing and CRC-16 (python-can interface
    `hilserial`), on loop_serial.c."""


_FACES: dict[type[WireEnd], type[WireBus]] = {UdpEnd: HilUdpBus, SerialEnd: HilSerialBus}


def python_can_face(end: WireEnd) -> WireBus:
    """`end` as the python-can bus of its kind (`HilUdpBus`, `HilSerialBus`): the same object on the same C state,
    its class changed and python-can's bus state added (filters from the options it was opened with); shut down
    if it was. An end that is a python-can bus already is returned as it is."""
    if isinstance(end, WireBus):
        return end
    face = _FACES[type(end)]
    was_shut = end._is_shutdown
    end.__class__ = face
    bus: WireBus = end  # type: ignore[assignment]
    bus._python_can_state()
    bus._is_shutdown = was_shut
    return bus


__all__ = ["DEFAULT_RCVBUF", "CanUdpSessionError", "CanWireError", "CanWireInitError", "HilSerialBus", "HilUdpBus",
           "UdpSessionError", "WireBus", "WireLinkStats", "free_udp_ports", "link_socket_drops",
           "parse_udp_channel", "python_can_face", "udp_socket_drops"]
