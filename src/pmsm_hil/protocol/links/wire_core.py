"""The C wire links' ends without python-can: what a run's host and a spawned target use of the hiludp / hilserial
buses (frames in and out, the UDP session, the C state the period loop drives).

A link opened by `open_link("udp...")` / `open_link("serial...")` is one of these ends (`UdpEnd`, `SerialEnd`);
python-can's package (≈ 0.3 CPU-s to import: its entry-point scan, asyncio, its log readers and writers) is
imported only when its bus is asked for (`BusLink.bus`): the end then becomes the python-can bus of its kind, the
same object on the same C state (`wire_bus.python_can_face`). `can.Bus(interface="hiludp" / "hilserial")` opens
that bus directly (wire_bus.py). The framing, CRC, link sequence numbers, session handshake and authentication
are the C links of the period loop (loop_udp.c, loop_serial.c, nl_link.c), compiled into `_wire_native`.
"""

from __future__ import annotations

import logging
import os
import re
import socket
import struct
import time
from collections import deque
from typing import Any, NamedTuple, Self

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
NEVER_NS = 2**63 - 1
#: answers to a HELLO refused for its authentication (loop_udp.c): the refusing end authenticates and the MAC
#: failed (its key differs), or it does not authenticate and the HELLO did
REJECT_KEY, REJECT_PLAIN = 3, 4
_LOG = logging.getLogger(__name__)


class WireError(LinkError):
    """A wire end cannot send or receive (an I/O error, a frame the wire cannot carry, the end shut down)."""


class WireInitError(LinkError):
    """A wire end cannot be opened (a bad channel, a port or socket refused); names the channel."""


class UdpSessionError(LinkError):
    """No UDP session was agreed with the peer (it refused our HELLO or did not answer); names the peer and why."""


class Queued(NamedTuple):
    """A frame held for the next receive: received while a UDP end waited for its session, or (python-can's
    `receive_own_messages`) one this end sent. `flags`: the wire's NL_WIRE_* bits; `data` None for a remote frame."""

    arbitration_id: int
    flags: int
    dlc: int
    data: bytes | None
    timestamp: float
    is_rx: bool


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


def link_end(link: Any) -> Any:
    """The end a link was opened on, through the wrappers that hold it as `.link` (fault injection, the loop's
    facades): a wire end of this module, a python-can bus, or None. Reading it never imports python-can (a link's
    `bus` may: `BusLink.bus`)."""
    seen = 0
    while link is not None and seen < 16:
        end = getattr(link, "end", None)
        if end is not None:
            return end
        link, seen = getattr(link, "link", None), seen + 1
    return None


def link_socket_drops(link: Any) -> dict[str, int]:
    """{"socket_drops": N} for a link over hiludp whose kernel count is known, else {} (LinkStats extras)."""
    end = link_end(link)
    drops = udp_socket_drops(end.fileno()) if isinstance(end, UdpEnd) and not end._is_shutdown else None
    return {} if drops is None else {"socket_drops": drops}


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


def deadline_ns(timeout_s: float) -> int:
    """CLOCK_MONOTONIC [ns] `timeout_s` from now."""
    return int(lib.nl_now_ns()) + max(0, int(timeout_s * 1e9))


def _ipv4(address: str) -> int:
    """An IPv4 address as the u32 of its network-order bytes."""
    value: int = struct.unpack("=I", socket.inet_aton(address))[0]
    return value


class WireEnd:
    """One end of a C wire link; subclasses open it (`_state`) and name its send / receive / close. The errors it
    raises are its class's `_op_error`, `_init_error`, `_session_error` (python-can's on its python-can face)."""

    _state: Any
    _kind = "wire"
    _op_error: type[Exception] = WireError
    _init_error: type[Exception] = WireInitError
    _session_error: type[Exception] = UdpSessionError
    _is_shutdown = True  # until opened (python-can's convention)
    channel_info = "unknown"

    def __init__(self, channel: Any, *, fd: bool = True, receive_own_messages: bool = False,
                 auth_key: bytes | None = None, auth_role: str = "host", **kwargs: Any) -> None:
        self.fd = bool(fd)
        self.receive_own_messages = bool(receive_own_messages)
        #: received channel name: the channel as given, whitespace replaced (python-can's logs split on it)
        self.channel_name = re.sub(r"\s+", "_", str(channel))
        self._queued: deque[Queued] = deque()  # own frames, frames received while waiting for a session
        #: the C link's counters, live (LinkStats names)
        self.link_stats: LinkStats = WireLinkStats(self._state.stats)
        self._tx_frame = ffi.new("nl_wire_frame_t *")
        self._rx_frame = ffi.new("nl_wire_frame_t *")
        if auth_key is not None and lib.hil_auth_init(ffi.addressof(self._state, "auth"), auth_key, len(auth_key),
                                                      1 if auth_role == "target" else 0) != 0:
            self._close()
            raise self._init_error(f"{self._kind}: an authentication key of {len(auth_key)} bytes is refused (see "
                                   "docs/protocol.md for the key lengths)")
        self._opened(channel, kwargs)

    def _opened(self, channel: Any, kwargs: dict[str, Any]) -> None:
        """The end is open: the options python-can's bus takes (filters, ...) are kept for its python-can face."""
        self.channel = channel
        self._face_kwargs = kwargs
        self._is_shutdown = False

    # -- what a subclass supplies --
    def _send_wire(self, m: Any, deadline_ns: int) -> int:
        raise NotImplementedError

    def _recv_wire(self, m: Any, deadline_ns: int) -> int:
        raise NotImplementedError

    def _close(self) -> None:
        raise NotImplementedError

    def _tx_seq(self) -> int:
        raise NotImplementedError

    # -- the end --
    @property
    def end(self) -> WireEnd:
        """This end (`link_end` of a bare end)."""
        return self

    def fileno(self) -> int:
        """The socket's or port's descriptor."""
        return int(self._state.fd)

    def _check_open(self) -> None:
        """An error once the end is shut down (a receive waiting in another thread then ends)."""
        if self._is_shutdown:
            raise self._op_error(f"{self.channel_info}: the bus is shut down")

    def shutdown(self) -> None:
        """Close the link (idempotent)."""
        if self._is_shutdown:
            return
        self._is_shutdown = True
        self._close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc: object) -> None:
        self.shutdown()

    def __del__(self) -> None:
        if not self._is_shutdown:
            _LOG.warning("%s was not properly shut down", type(self).__name__)
            self.shutdown()

    @staticmethod
    def _received(m: Any) -> Queued:
        """The frame in the receive buffer `m` (after `_recv_wire` returned 1), held."""
        flags = int(m.flags)
        remote = bool(flags & lib.NL_WIRE_REMOTE)
        return Queued(int(m.id), flags, int(m.len), None if remote else ffi.buffer(m.data, m.len)[:], time.time(),
                      True)

    def send_frame(self, arbitration_id: int, data: bytes, is_fd: bool) -> None:
        """Send an 11-bit data frame (FD frames with BRS); an error for a frame the wire cannot carry or an I/O
        error."""
        m = self._tx_frame
        n = len(data)
        if n > 64 or (is_fd and not self.fd):
            self._state.stats.send_errors += 1
            raise self._op_error(f"{self.channel_info}: payload length {n} invalid for "
                                 f"{'FD' if is_fd else 'classic'} frame" + ("" if self.fd or not is_fd
                                                                            else " (fd=False)"))
        m.id = arbitration_id
        m.flags = (lib.NL_WIRE_FD | lib.NL_WIRE_BRS) if is_fd else 0
        m.len = n
        ffi.memmove(m.data, data, n)
        self._sent(self._send_wire(m, deadline_ns(1.0)), f"payload length {n} invalid for "
                   f"{'FD' if is_fd else 'classic'} frame")

    def _sent(self, rc: int, cannot_carry: str) -> None:
        """Raise for a send's return code (-2: the wire cannot carry the frame, < 0: an I/O error)."""
        if rc == -2:
            raise self._op_error(f"{self.channel_info}: {cannot_carry}")
        if rc < 0:
            errno = ffi.errno
            raise self._op_error(f"{self.channel_info}: send failed: "
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
        skip = lib.NL_WIRE_EXTENDED | lib.NL_WIRE_REMOTE
        while True:
            if self._queued:
                q = self._queued.popleft()
                if q.flags & skip:
                    self._state.stats.ignored += 1
                    continue
                return Frame(q.arbitration_id, q.data or b"", bool(q.flags & lib.NL_WIRE_FD))
            if self._recv_wire(m, deadline_ns) != 1:
                return None
            flags = int(m.flags)
            if flags & skip:
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


class UdpEnd(WireEnd):
    """Point-to-point UDP (`hiludp`) with a per-session handshake, on loop_udp.c. Channel "LOCALPORT:REMOTEPORT[@HOST]"
    (HOST default 127.0.0.1); the receive buffer is `rcvbuf` bytes (forced past the system limit where the process
    may)."""

    _kind = "hiludp"

    def __init__(self, channel: Any = None, *, rcvbuf: int = DEFAULT_RCVBUF, **kwargs: Any) -> None:
        if channel is None:
            raise self._init_error("hiludp needs channel='LOCALPORT:REMOTEPORT[@HOST]'")
        try:
            local, remote, host = parse_udp_channel(channel)
            peer_ip = socket.gethostbyname(host)
        except (ValueError, OSError) as exc:
            raise self._init_error(f"hiludp channel {channel!r}: {exc}") from exc
        self._state = ffi.new("nl_udp_t *")
        bind_ip = "127.0.0.1" if host in ("127.0.0.1", "localhost") else "0.0.0.0"
        err = lib.nl_udp_open(self._state, _ipv4(bind_ip), socket.htons(local), _ipv4(peer_ip), socket.htons(remote),
                              int(rcvbuf))
        if err:
            raise self._init_error(f"hiludp: cannot bind UDP port {local}: {os.strerror(err)} (the link towards "
                                   f"{peer_ip}:{remote})")
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
        are kept for the next receives); an error naming the peer and why when it refuses or does not answer."""
        u = self._state
        if not u.session and not u.proposal:
            lib.nl_udp_propose(u)
        deadline = deadline_ns(timeout_s)
        m = ffi.new("nl_wire_frame_t *")
        while u.proposal or not u.session:
            if u.rejected:
                raise self._session_error(f"{self.channel_info}: no session agreed: {self._rejection(int(u.rejected))}")
            if lib.nl_now_ns() >= deadline:
                raise self._session_error(f"{self.channel_info}: no session agreed: {self._silence(timeout_s)}")
            if self._recv_wire(m, min(deadline, deadline_ns(0.05))) == 1:
                self._queued.append(self._received(m))

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


class SerialEnd(WireEnd):
    """Frames over a serial line (UART, USB CDC, pty) with COBS framing and CRC-16 (`hilserial`), on loop_serial.c.
    Channel: a serial device (/dev/ttyACM0), a pyserial URL whose port has a descriptor, or "fd:N" for an open
    descriptor the end then owns (a pty end from os.openpty(), in raw mode)."""

    _kind = "hilserial"

    def __init__(self, channel: Any = None, *, baudrate: int = DEFAULT_BAUDRATE, fd: bool = True,
                 write_timeout: float = DEFAULT_WRITE_TIMEOUT_S, **kwargs: Any) -> None:
        if channel is None:
            raise self._init_error("hilserial needs channel=PORT, URL or fd:N")
        chan = str(channel)
        self._port: Any = None
        if chan.startswith("fd:"):
            try:
                descriptor = int(chan[3:])
            except ValueError as exc:
                raise self._init_error(f"hilserial: cannot open {chan!r} as a port with a file descriptor "
                                       f"(a device, a pty, fd:N): {exc}") from exc
        else:
            descriptor = self._open_port(chan, int(baudrate))
        self._state = ffi.new("nl_serial_t *")
        err = lib.nl_serial_attach(self._state, descriptor, int(bool(fd)), int(write_timeout * 1e9))
        if err:
            self._close()
            raise self._init_error(f"hilserial: cannot use {chan!r}: {os.strerror(err)}")
        self.channel_info = f"hilserial {chan}"
        super().__init__(channel, fd=fd, **kwargs)

    def _open_port(self, chan: str, baudrate: int) -> int:
        """The descriptor of the port `chan` opened by pyserial (imported here: only where a port is opened)."""
        import serial

        try:
            self._port = serial.serial_for_url(chan, baudrate=baudrate, timeout=0, write_timeout=None)
            return int(self._port.fileno())
        except (ValueError, OSError, AttributeError, NotImplementedError, serial.SerialException) as exc:
            if self._port is not None:
                self._port.close()
            raise self._init_error(f"hilserial: cannot open {chan!r} as a port with a file descriptor "
                                   f"(a device, a pty, fd:N): {exc}") from exc

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


__all__ = ["DEFAULT_RCVBUF", "SerialEnd", "UdpEnd", "UdpSessionError", "WireEnd", "WireError", "WireInitError",
           "WireLinkStats", "deadline_ns", "free_udp_ports", "link_end", "link_socket_drops", "parse_udp_channel",
           "udp_socket_drops"]
