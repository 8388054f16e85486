"""python-can interfaces `hiludp` and `hilserial` on the C wire links.

The framing, CRC, link sequence numbers, UDP session handshake and frame authentication of both wires are the C
links of the period loop (src/pmsm_hil/hil/runner/c/links: loop_udp.c, loop_serial.c, nl_link.c), compiled once
more into the extension `_wire_native` (_build_wire.py): each wire is written once, in C. This module is only the
python-can face, modelled on python-can's own buses (`BusABC._recv_internal`, `VirtualBus`): Messages in and out,
timeouts, `receive_own_messages`, and filters (by BusABC).

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

import os
import re
import socket
import struct
import time
from collections import deque
from typing import Any

import can
from can import CanProtocol

from pmsm_hil.protocol.errors import LinkError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links._wire_native import ffi, lib
from pmsm_hil.protocol.links.stats import LinkStats

#: a receive without a timeout returns to Python this often [s] (a shutdown from another thread ends it)
WAIT_SLICE_S = 0.25
#: the UDP receive buffer asked for [bytes]: 1000 small frames take ~1 MiB of kernel memory on loopback
DEFAULT_RCVBUF = 4 << 20
DEFAULT_HOST = "127.0.0.1"
DEFAULT_BAUDRATE = 115200
#: a serial output buffer full for this long makes the frame a send error [s]
DEFAULT_WRITE_TIMEOUT_S = 1.0
#: an authenticated UDP end waits this long for the session its first frame needs [s]
AUTH_SESSION_WAIT_S = 10.0
_NEVER_NS = 2**63 - 1
#: answers to a HELLO refused for its authentication (loop_udp.c): the refusing end authenticates and the MAC
#: failed (its key differs), or it does not authenticate and the HELLO did
REJECT_KEY, REJECT_PLAIN = 3, 4


class UdpSessionError(LinkError, can.CanOperationError):
    """No UDP session was agreed with the peer (it refused our HELLO or did not answer); names the peer and why."""


def parse_udp_channel(channel: str) -> tuple[int, int, str]:
    """ "LOCAL:REMOTE[@HOST]" -> (local port, remote port, host); raises ValueError naming the part."""
    ports, _, host = str(channel).partition("@")
    parts = ports.split(":")
    if len(parts) != 2:
        raise ValueError(f"UDP channel {channel!r}: expected LOCALPORT:REMOTEPORT[@HOST]")
    try:
        local, remote = int(parts[0]), int(parts[1])
    except ValueError:
        raise ValueError(f"UDP channel {channel!r}: ports must be integers") from None
    for name, port in (("LOCALPORT", local), ("REMOTEPORT", remote)):
        if not 0 <= port <= 65535 or (name == "REMOTEPORT" and port == 0):
            raise ValueError(f"UDP channel {channel!r}: {name}={port} out of range")
    return local, remote, host or DEFAULT_HOST


def free_udp_ports(n: int = 2, host: str = DEFAULT_HOST) -> list[int]:
    """`n` distinct UDP ports free on `host` now (bound to port 0 together, then released)."""
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(n)]
    try:
        for s in socks:
            s.bind((host, 0))
        return [int(s.getsockname()[1]) for s in socks]
    finally:
        for s in socks:
            s.close()


def udp_socket_drops(fd: int) -> int | None:
    """`drops` of the UDP socket `fd` in /proc/net/udp (found by its inode), None where that is not known."""
    try:
        inode = str(os.fstat(fd).st_ino)
        with open("/proc/net/udp", encoding="ascii") as table:
            for line in table:
                fields = line.split()
                if len(fields) >= 13 and fields[9] == inode:
                    return int(fields[12])
    except (OSError, ValueError):
        return None
    return None


def link_socket_drops(link: Any) -> dict[str, int]:
    """{"socket_drops": N} for a link over hiludp whose kernel count is known, else {} (LinkStats extras)."""
    bus = getattr(link, "bus", None)
    drops = udp_socket_drops(bus.fileno()) if isinstance(bus, HilUdpBus) and not bus._is_shutdown else None
    return {} if drops is None else {"socket_drops": drops}


def _flags(msg: can.Message) -> int:
    """The wire flags of a Message."""
    return ((lib.NL_WIRE_FD if msg.is_fd else 0) | (lib.NL_WIRE_BRS if msg.bitrate_switch else 0)
            | (lib.NL_WIRE_ESI if msg.error_state_indicator else 0)
            | (lib.NL_WIRE_EXTENDED if msg.is_extended_id else 0)
            | (lib.NL_WIRE_REMOTE if msg.is_remote_frame else 0))


class WireLinkStats(LinkStats):
    """`LinkStats` read from and written to the C link's counters (nl_link_stats_t): a live view, so what the
    period loop counts on the bus's own C state is what the bus reports."""

    __slots__ = ("_c",)

    def __init__(self, c_stats: Any) -> None:
        self._c = c_stats


def _live_counter(name: str) -> property:
    def get(self: WireLinkStats) -> int:
        return int(getattr(self._c, name))

    def put(self: WireLinkStats, value: int) -> None:
        setattr(self._c, name, value)

    return property(get, put, doc=f"the C link's `{name}` counter")


for _name in LinkStats.__slots__:
    setattr(WireLinkStats, _name, _live_counter(_name))


class WireBus(can.BusABC):
    """A python-can bus on one C wire link; subclasses open it (`_state`) and name its send / receive / close."""

    _state: Any
    _kind = "wire"

    def __init__(self, channel: Any, *, fd: bool = True, receive_own_messages: bool = False,
                 auth_key: bytes | None = None, auth_role: str = "host", **kwargs: Any) -> None:
        self.fd = bool(fd)
        self._can_protocol = CanProtocol.CAN_FD if self.fd else CanProtocol.CAN_20
        self.receive_own_messages = bool(receive_own_messages)
        #: received channel name: the channel as given, whitespace replaced (python-can's logs split on it)
        self.channel_name = re.sub(r"\s+", "_", str(channel))
        self._queued: deque[can.Message] = deque()  # own messages, frames received while waiting for a session
        #: the C link's counters, live (LinkStats names)
        self.link_stats: LinkStats = WireLinkStats(self._state.stats)
        self._tx_frame = ffi.new("nl_wire_frame_t *")
        self._rx_frame = ffi.new("nl_wire_frame_t *")
        if auth_key is not None and lib.hil_auth_init(ffi.addressof(self._state, "auth"), auth_key, len(auth_key),
                                                      1 if auth_role == "target" else 0) != 0:
            self._close()
            raise can.CanInitializationError(f"{self._kind}: an authentication key of {len(auth_key)} bytes is "
                                             "refused (see docs/protocol.md for the key lengths)")
        super().__init__(channel=channel, **kwargs)

    # -- what a subclass supplies --
    def _send_wire(self, m: Any, deadline_ns: int) -> int:
        raise NotImplementedError

    def _recv_wire(self, m: Any, deadline_ns: int) -> int:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError

    # -- python-can API --
    def fileno(self) -> int:
        """The socket's or port's descriptor (select-based notifiers)."""
        return int(self._state.fd)

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """Send `msg`; CanOperationError for a frame the wire cannot carry or an I/O error."""
        self._check_open()
        if msg.is_error_frame:
            raise can.CanOperationError(f"{self.channel_info}: error frames are not carried")
        data = b"" if msg.is_remote_frame else bytes(msg.data)
        if msg.is_fd and not self.fd:
            self._state.stats.send_errors += 1
            raise can.CanOperationError(f"{self.channel_info}: an FD frame on a classic bus (fd=False)")
        if len(data) > 64 or (msg.is_remote_frame and not 0 <= msg.dlc <= 8):
            raise can.CanOperationError(f"{self.channel_info}: a frame of {len(data) or msg.dlc} bytes")
        m = ffi.new("nl_wire_frame_t *")
        m.id = msg.arbitration_id
        m.flags = _flags(msg)
        m.len = msg.dlc if msg.is_remote_frame else len(data)
        ffi.memmove(m.data, data, len(data))
        rc = self._send_wire(m, _deadline_ns(1.0 if timeout is None else timeout))
        if rc == -2:
            raise can.CanOperationError(
                f"{self.channel_info}: the wire cannot carry this frame (id 0x{msg.arbitration_id:X}, "
                f"{'FD' if msg.is_fd else 'classic'}, {len(data)} bytes)")
        if rc < 0:
            errno = ffi.errno
            raise can.CanOperationError(f"{self.channel_info}: send failed: "
                                        + (os.strerror(errno) if errno else "the output stayed full"))
        if self.receive_own_messages:
            self._queued.append(can.Message(
                timestamp=time.time(), arbitration_id=msg.arbitration_id, is_extended_id=msg.is_extended_id,
                is_remote_frame=msg.is_remote_frame, is_fd=msg.is_fd, bitrate_switch=msg.bitrate_switch,
                error_state_indicator=msg.error_state_indicator, dlc=msg.dlc, data=data or None,
                channel=self.channel_name, is_rx=False))

    def _check_open(self) -> None:
        """CanOperationError once the bus is shut down (a receive waiting in another thread then ends)."""
        if self._is_shutdown:
            raise can.CanOperationError(f"{self.channel_info}: the bus is shut down")

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        self._check_open()
        deadline = _NEVER_NS if timeout is None else _deadline_ns(timeout)
        m = ffi.new("nl_wire_frame_t *")
        while not self._queued:
            now = lib.nl_now_ns()
            got = self._recv_wire(m, min(deadline, now + int(WAIT_SLICE_S * 1e9)))
            if got == 1:
                return self._message(m), False
            if got < 0:
                raise can.CanOperationError(f"{self.channel_info}: the peer closed the link")
            self._check_open()
            if lib.nl_now_ns() >= deadline:
                return None, False
        return self._queued.popleft(), False

    def _message(self, m: Any) -> can.Message:
        flags = int(m.flags)
        remote = bool(flags & lib.NL_WIRE_REMOTE)
        return can.Message(
            timestamp=time.time(), arbitration_id=int(m.id), is_extended_id=bool(flags & lib.NL_WIRE_EXTENDED),
            is_remote_frame=remote, is_fd=bool(flags & lib.NL_WIRE_FD),
            bitrate_switch=bool(flags & lib.NL_WIRE_BRS), error_state_indicator=bool(flags & lib.NL_WIRE_ESI),
            dlc=int(m.len), data=None if remote else bytes(ffi.buffer(m.data, m.len)), channel=self.channel_name,
            is_rx=True)

    def shutdown(self) -> None:
        """Close the link (python-can API; idempotent)."""
        if self._is_shutdown:
            return
        super().shutdown()
        self._close()

    # -- the fast path of a Link (link.py): frames without can.Message --
    def send_frame(self, arbitration_id: int, data: bytes, is_fd: bool) -> None:
        """Send an 11-bit data frame (FD frames with BRS); CanOperationError for a frame the wire cannot carry or
        an I/O error."""
        m = self._tx_frame
        n = len(data)
        if n > 64 or (is_fd and not self.fd):
            self._state.stats.send_errors += 1
            raise can.CanOperationError(f"{self.channel_info}: payload length {n} invalid for "
                                        f"{'FD' if is_fd else 'classic'} frame" + ("" if self.fd or not is_fd
                                                                                   else " (fd=False)"))
        m.id = arbitration_id
        m.flags = (lib.NL_WIRE_FD | lib.NL_WIRE_BRS) if is_fd else 0
        m.len = n
        ffi.memmove(m.data, data, n)
        rc = self._send_wire(m, _deadline_ns(1.0))
        if rc == -2:
            raise can.CanOperationError(f"{self.channel_info}: payload length {n} invalid for "
                                        f"{'FD' if is_fd else 'classic'} frame")
        if rc < 0:
            errno = ffi.errno
            raise can.CanOperationError(f"{self.channel_info}: send failed: "
                                        + (os.strerror(errno) if errno else "the output stayed full"))

    def poll_frame(self) -> Frame | None:
        """The next 11-bit data frame received, or None at once; extended and remote frames are counted as
        ignored (frames queued while waiting for a session come first)."""
        return self.next_frame(0)

    def next_frame(self, deadline_ns: int) -> Frame | None:
        """The next 11-bit data frame received before `deadline_ns` (CLOCK_MONOTONIC [ns]; 0: None at once), waited
        for in the wire's own receive (blocked in ppoll, not spinning); None after the deadline or when the peer
        closed the link. Extended and remote frames are counted as ignored (poll_frame)."""
        m = self._rx_frame
        while True:
            if self._queued:
                msg = self._queued.popleft()
                if msg.is_extended_id or msg.is_remote_frame:
                    self._state.stats.ignored += 1
                    continue
                return Frame(msg.arbitration_id, bytes(msg.data), msg.is_fd)
            if self._recv_wire(m, deadline_ns) != 1:
                return None
            flags = int(m.flags)
            if flags & (lib.NL_WIRE_EXTENDED | lib.NL_WIRE_REMOTE):
                self._state.stats.ignored += 1
                continue
            return Frame(int(m.id), ffi.buffer(m.data, m.len)[:], bool(flags & lib.NL_WIRE_FD))

    @property
    def authenticated(self) -> bool:
        """Frames on this bus carry the authentication trailer (an `auth_key` was given)."""
        return bool(self._state.auth.on)

    @property
    def c_state_address(self) -> int:
        """The address of the bus's C link state (nl_udp_t / nl_serial_t): what the period loop drives for a run."""
        return int(ffi.cast("uintptr_t", self._state))

    @property
    def c_state_size(self) -> int:
        """The size of that state [bytes] (the loop's extension checks its own type against it)."""
        return int(ffi.sizeof(ffi.typeof(self._state).item))

    @property
    def link_seq(self) -> tuple[int, int]:
        """(next link sequence number sent, last one received or -1)."""
        return self._tx_seq(), int(self._state.rx_last)

    def _tx_seq(self) -> int:
        raise NotImplementedError


def _deadline_ns(timeout_s: float) -> int:
    """CLOCK_MONOTONIC [ns] `timeout_s` from now."""
    return int(lib.nl_now_ns()) + max(0, int(timeout_s * 1e9))


def _ipv4(address: str) -> int:
    """An IPv4 address as the u32 of its network-order bytes."""
    value: int = struct.unpack("=I", socket.inet_aton(address))[0]
    return value


class HilUdpBus(WireBus):
    """Point-to-point UDP bus (python-can interface `hiludp`) with a per-session handshake, on loop_udp.c."""

    _kind = "hiludp"

    def __init__(self, channel: Any = None, *, rcvbuf: int = DEFAULT_RCVBUF, **kwargs: Any) -> None:
        if channel is None:
            raise can.CanInitializationError("hiludp needs channel='LOCALPORT:REMOTEPORT[@HOST]'")
        try:
            local, remote, host = parse_udp_channel(channel)
            peer_ip = socket.gethostbyname(host)
        except (ValueError, OSError) as exc:
            raise can.CanInitializationError(f"hiludp channel {channel!r}: {exc}") from exc
        self._state = ffi.new("nl_udp_t *")
        bind_ip = "127.0.0.1" if host in ("127.0.0.1", "localhost") else "0.0.0.0"
        err = lib.nl_udp_open(self._state, _ipv4(bind_ip), socket.htons(local), _ipv4(peer_ip), socket.htons(remote),
                              int(rcvbuf))
        if err:
            raise can.CanInitializationError(f"hiludp: cannot bind UDP port {local}: {os.strerror(err)} (the link "
                                             f"towards {peer_ip}:{remote})")
        self.local_port = int(lib.nl_udp_local_port(self._state))
        self.peer = (peer_ip, remote)
        self.channel_info = f"hiludp {self.local_port}->{peer_ip}:{remote}"
        super().__init__(channel, **kwargs)

    @property
    def rcvbuf(self) -> int:
        """The receive buffer the kernel granted [bytes]."""
        return int(self._state.rcvbuf)

    def kernel_dropped(self) -> int:
        """Datagrams the kernel dropped for this socket, its receive buffer full: the SO_RXQ_OVFL count the last
        datagram received carried, or the socket's `drops` in /proc/net/udp where that is higher (drops after the
        last datagram received show there at once)."""
        return max(int(self._state.kernel_drops), udp_socket_drops(self.fileno()) or 0)

    @property
    def session(self) -> int:
        """The session id in use (0: none yet; this end's proposal, unauthenticated, before the peer agreed)."""
        return int(self._state.session)

    @property
    def nonce(self) -> int:
        """The adopting end's nonce of the session in use (authenticated links; 0: none)."""
        return int(self._state.nonce)

    @property
    def connected(self) -> bool:
        """The socket is connect()ed to the peer: the kernel delivers only the peer's datagrams."""
        with socket.socket(fileno=os.dup(self.fileno())) as sock:
            try:
                sock.getpeername()
            except OSError:
                return False
        return True

    def socket_drops(self) -> int | None:
        """Datagrams the kernel dropped for this socket (its receive buffer full: `drops` of /proc/net/udp), None
        where that is not known."""
        return udp_socket_drops(self.fileno())

    def propose(self) -> None:
        """Start the handshake with a fresh random session id (HELLO, repeated by the receives until answered)."""
        lib.nl_udp_propose(self._state)

    @property
    def established(self) -> bool:
        """True once both ends use the same session."""
        return bool(self._state.session) and not self._state.proposal

    def wait_session(self, timeout_s: float) -> None:
        """Propose a session unless one is in use and receive until the peer agreed (frames that arrive meanwhile
        are kept for recv); UdpSessionError naming the peer and why when it refuses or does not answer."""
        u = self._state
        if not u.session and not u.proposal:
            lib.nl_udp_propose(u)
        deadline = _deadline_ns(timeout_s)
        m = ffi.new("nl_wire_frame_t *")
        while u.proposal or not u.session:
            if u.rejected:
                raise UdpSessionError(f"{self.channel_info}: no session agreed: {self._rejection(int(u.rejected))}")
            if lib.nl_now_ns() >= deadline:
                raise UdpSessionError(f"{self.channel_info}: no session agreed: {self._silence(timeout_s)}")
            if self._recv_wire(m, min(deadline, _deadline_ns(0.05))) == 1:
                self._queued.append(self._message(m))

    def _rejection(self, kind: int) -> str:
        peer = f"{self.peer[0]}:{self.peer[1]}"
        if kind == REJECT_KEY and self._state.auth.on:
            return (f"the peer at {peer} refused our HELLO: its authentication key differs from this end's "
                    "(the same key=HEX / keyfile=PATH on both ends)")
        if kind == REJECT_KEY:
            return (f"the peer at {peer} authenticates frames and this end does not: give this end its key "
                    "(key=HEX or keyfile=PATH in the link SPEC)")
        return (f"the peer at {peer} does not authenticate frames and this end does: start it with the same key "
                "(key=HEX or keyfile=PATH), or drop the key here")

    def _silence(self, timeout_s: float) -> str:
        """Why no session was agreed within `timeout_s` [s], from what the peer sent meanwhile."""
        peer = f"{self.peer[0]}:{self.peer[1]}"
        s = self._state.stats
        if s.auth_failed:
            return (f"the peer at {peer} answers with authentication that fails ({s.auth_failed} datagrams "
                    "dropped): " + ("its key differs from this end's" if self._state.auth.on else
                                    "it authenticates frames and this end does not (key=HEX or keyfile=PATH)"))
        if s.session_dropped or s.framing_errors:
            return (f"the peer at {peer} answers without the hiludp session handshake "
                    f"({s.session_dropped + s.framing_errors} datagrams dropped): an old or foreign target, "
                    "see docs/protocol.md")
        why = f"no answer from the peer at {peer} within {timeout_s:g} s (is a target running there?"
        return why + (" Does it authenticate frames?)" if self._state.auth.on else ")")

    def _send_wire(self, m: Any, deadline_ns: int) -> int:
        rc = int(lib.nl_udp_send_wire(self._state, m, deadline_ns))
        if rc == -3:  # authenticated: the frames need the agreed session's MAC context first
            self.wait_session(AUTH_SESSION_WAIT_S)
            rc = int(lib.nl_udp_send_wire(self._state, m, deadline_ns))
        return rc

    def _recv_wire(self, m: Any, deadline_ns: int) -> int:
        return int(lib.nl_udp_recv_wire(self._state, m, deadline_ns))

    def _close(self) -> None:
        lib.nl_udp_close(self._state)

    def _tx_seq(self) -> int:
        return int(self._state.tx_seq)


class HilSerialBus(WireBus):
    """Frames over a serial line (UART, USB CDC, pty) with COBS framing and CRC-16 (python-can interface
    `hilserial`), on loop_serial.c."""

    _kind = "hilserial"

    def __init__(self, channel: Any = None, *, baudrate: int = DEFAULT_BAUDRATE, fd: bool = True,
                 write_timeout: float = DEFAULT_WRITE_TIMEOUT_S, **kwargs: Any) -> None:
        if channel is None:
            raise can.CanInitializationError("hilserial needs channel=PORT, URL or fd:N")
        import serial  # pyserial: where a serial link is opened, not in every process that imports the links

        chan = str(channel)
        self._port: Any = None
        try:
            if chan.startswith("fd:"):
                descriptor = int(chan[3:])
            else:
                self._port = serial.serial_for_url(chan, baudrate=int(baudrate), timeout=0, write_timeout=None)
                descriptor = int(self._port.fileno())
        except (ValueError, OSError, AttributeError, NotImplementedError, serial.SerialException) as exc:
            if self._port is not None:
                self._port.close()
            raise can.CanInitializationError(f"hilserial: cannot open {chan!r} as a port with a file descriptor "
                                             f"(a device, a pty, fd:N): {exc}") from exc
        self._state = ffi.new("nl_serial_t *")
        err = lib.nl_serial_attach(self._state, descriptor, int(bool(fd)), int(write_timeout * 1e9))
        if err:
            self._close()
            raise can.CanInitializationError(f"hilserial: cannot use {chan!r}: {os.strerror(err)}")
        self.channel_info = f"hilserial {chan}"
        super().__init__(channel, fd=fd, **kwargs)

    def _send_wire(self, m: Any, deadline_ns: int) -> int:
        return int(lib.nl_serial_send_wire(self._state, m))

    def _recv_wire(self, m: Any, deadline_ns: int) -> int:
        return int(lib.nl_serial_recv_wire(self._state, m, deadline_ns))

    def _close(self) -> None:
        if self._port is not None:
            self._port.close()
            self._state.fd = -1
        else:
            lib.nl_serial_close(self._state)

    def _tx_seq(self) -> int:
        return int(self._state.framer.tx_seq)


__all__ = ["DEFAULT_RCVBUF", "HilSerialBus", "HilUdpBus", "UdpSessionError", "WireBus", "WireLinkStats",
           "free_udp_ports", "link_socket_drops", "parse_udp_channel", "udp_socket_drops"]
