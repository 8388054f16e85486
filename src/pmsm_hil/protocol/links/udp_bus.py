"""python-can interface `hiludp`: unicast UDP, one frame per datagram, only with the configured peer.

channel: "LOCALPORT:REMOTEPORT[@HOST]" (HOST default 127.0.0.1). Non-blocking socket; the Link
wrapper busy-polls `poll_frame`. Example: can.Bus(interface="hiludp", channel="47310:47311").

Datagram = session id (u32 LE) + `wire` header + payload. Session 0 marks a control datagram (HELLO /
ACK, `CONTROL`): the first end that sends proposes a random session id, its peer adopts it and acks
(on a clash the larger id wins); both then drop datagrams of any other session. Datagrams from any
address but the peer's are dropped too: the socket is connect()ed to the peer when it opens, so the kernel drops
them before they reach it. docs/protocol.md, "UDP datagrams and session handshake".
"""

from __future__ import annotations

import binascii
import secrets
import socket
import struct
import time
from typing import Any

import can

from pmsm_hil.protocol.errors import LinkError
from pmsm_hil.protocol.links.auth import MAC_SIZE
from pmsm_hil.protocol.links.cobs import CRC_INIT, CRC_SIZE
from pmsm_hil.protocol.links.framed_bus import FramedBus
from pmsm_hil.protocol.links.stats import SeqTracker
from pmsm_hil.protocol.links.wire import HEADER_SIZE
from pmsm_hil.protocol.links.wire_bus import free_udp_ports, parse_udp_channel, udp_socket_drops

MAX_DATAGRAM = 2048
SESSION = struct.Struct("<I")
#: control datagram: session 0, magic, type, version, session id (14 bytes)
CONTROL = struct.Struct("<I4sBBI")
MAGIC = b"HILS"
VERSION = 1
HELLO = 1
ACK = 2
#: answers to a HELLO refused for its authentication: the refusing end authenticates and the MAC failed (its key
#: differs), or it does not authenticate and the HELLO did (session = the refused proposal; never authenticated)
REJECT_KEY = 3
REJECT_PLAIN = 4
#: an authenticated control datagram: CONTROL + nonce u32 (the adopting end's, 0 in a HELLO) + MAC (22 bytes)
NONCE = struct.Struct("<I")
AUTH_CONTROL_SIZE = CONTROL.size + NONCE.size + MAC_SIZE
#: an authenticating end that sends a frame before a session is agreed waits this long for one [s]
AUTH_SESSION_WAIT_S = 10.0
HELLO_INTERVAL_S = 0.1  # a proposal is repeated until acknowledged
#: data datagram: session + wire header + payload + CRC-16 (CCITT, init 0xFFFF, big endian, over header+payload)
_DATA_MIN = SESSION.size + HEADER_SIZE + CRC_SIZE
_LENGTH_AT = SESSION.size + HEADER_SIZE - 1  # offset of the header's payload length byte


def link_socket_drops(link: Any) -> dict[str, int]:
    """{"socket_drops": N} for a link over hiludp whose kernel count is known, else {} (LinkStats extras)."""
    bus = getattr(link, "bus", None)
    drops = bus.socket_drops() if isinstance(bus, UdpUnicastBus) else None
    return {} if drops is None else {"socket_drops": drops}


def _new_session_id() -> int:
    while True:
        sid = secrets.randbits(32)
        if sid:
            return sid


class UdpUnicastBus(FramedBus):
    """Point-to-point UDP bus (both ends on one host or across a network) with a per-run session."""

    def __init__(self, channel: Any = None, *, fd: bool = True, **kwargs: Any) -> None:
        if channel is None:
            raise can.CanInitializationError("hiludp needs channel='LOCALPORT:REMOTEPORT[@HOST]'")
        try:
            local, remote, host = parse_udp_channel(channel)
            peer_ip = socket.gethostbyname(host)
        except (ValueError, OSError) as exc:
            raise can.CanInitializationError(f"hiludp channel {channel!r}: {exc}") from exc
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind((host if host in ("127.0.0.1", "localhost") else "", local))
        except OSError as exc:
            self._sock.close()
            raise can.CanInitializationError(f"hiludp: cannot bind UDP port {local}: {exc}") from exc
        self._sock.setblocking(False)
        self._remote = (peer_ip, remote)
        self.local_port: int = self._sock.getsockname()[1]
        self.channel_info = f"hiludp {self.local_port}->{peer_ip}:{remote}"
        self.session = 0  #: session id in use (0: none yet)
        self._proposal = 0  # our own proposal while not acknowledged
        self._next_hello = 0.0
        self._tx_prefix = b""
        self._rx_prefix = b""  # session bytes of the agreed session (b"": none, every datagram takes the slow path)
        #: the socket is connect()ed to the peer: the kernel delivers only the peer's datagrams
        self.connected = False
        self.nonce = 0  #: the adopting end's nonce of the session in use (authenticated links)
        #: REJECT_KEY / REJECT_PLAIN when the peer refused our HELLO for its authentication (0: not refused)
        self.rejected = 0
        self._connect()
        super().__init__(channel=channel, fd=fd, **kwargs)
        self._data_min = _DATA_MIN + self.trailer

    @property
    def established(self) -> bool:
        """True once both ends use the same session."""
        return bool(self._rx_prefix)

    def fileno(self) -> int:
        """Socket descriptor (for select-based python-can notifiers)."""
        return self._sock.fileno()

    def socket_drops(self) -> int | None:
        """Datagrams the kernel dropped for this socket (its receive buffer full: `drops` of /proc/net/udp), None
        where that is not known (not Linux, a closed socket)."""
        return udp_socket_drops(self._sock.fileno())

    @property
    def peer(self) -> tuple[str, int]:
        """The peer's (IPv4 address, port): the only sender accepted."""
        return self._remote

    # -- session handshake --
    def _control(self, kind: int, sid: int, nonce: int = 0) -> None:
        dgram = CONTROL.pack(0, MAGIC, kind, VERSION, sid)
        if self.auth is not None and kind in (HELLO, ACK):
            dgram += NONCE.pack(nonce)
            dgram += self.auth.control_mac(self.auth.tx_dir, dgram)
        try:
            self._sock.sendto(dgram, self._remote)
        except ConnectionRefusedError:  # an earlier HELLO refused (the peer not listening yet): resent later
            self._refused()
        except OSError:
            self.link_stats.send_errors += 1

    def _use(self, sid: int, agreed: bool, nonce: int = 0) -> None:
        if self.session and sid != self.session:  # the peer started a new run: forget the old one's frames
            self._rx.clear()
            self._tracker = SeqTracker(self.link_stats)
        self.session = sid
        self._tx_prefix = SESSION.pack(sid)
        self._rx_prefix = self._tx_prefix if agreed else b""
        self._proposal = 0 if agreed else sid
        if agreed:
            self.nonce = nonce
            if self.auth is not None:  # the frames' MACs bind the session and nonce; freshness starts again
                self.auth.set_context(SESSION.pack(sid) + NONCE.pack(nonce))
            self._connect()

    def _connect(self) -> None:
        """Connect the socket to the peer (at open, the peer's address and port being configured; retried when a
        session is agreed): the kernel then delivers only the peer's datagrams, so junk from other addresses never
        fills the receive buffer (it is dropped before this socket) and `socket_drops` counts the peer's only."""
        if self.connected:
            return
        try:
            self._sock.connect(self._remote)
        except OSError:  # the address filter in `_pump` still applies
            return
        self.connected = True

    def _refused(self) -> None:
        """ECONNREFUSED: the peer's host refused an earlier datagram (ICMP port unreachable, reported on a
        connected socket): a send error once a session is agreed; before, a HELLO to a peer not listening yet."""
        if self.established:
            self.link_stats.send_errors += 1

    def propose(self) -> None:
        """Start the handshake with a fresh random session id (HELLO, repeated until acknowledged)."""
        self.rejected = 0
        self._use(_new_session_id(), agreed=False)
        self._control(HELLO, self._proposal)
        self._next_hello = time.perf_counter() + HELLO_INTERVAL_S

    def wait_session(self, timeout_s: float) -> None:
        """Propose a session if none is in use and pump until the peer agreed; raises LinkError naming the peer."""
        if not self.session:
            self.propose()
        deadline = time.perf_counter() + timeout_s
        while not self.established:
            if self.rejected:
                raise LinkError(f"{self.channel_info}: no session agreed: {self._rejection()}")
            if time.perf_counter() > deadline:
                peer = f"{self._remote[0]}:{self._remote[1]}"
                s = self.link_stats
                if s.auth_failed:
                    why = (f"the peer at {peer} answers with authentication that fails ({s.auth_failed} datagrams "
                           "dropped): " + ("its key differs from this end's" if self.auth is not None else
                                           "it authenticates frames and this end does not (key=HEX or keyfile=PATH)"))
                elif s.session_dropped or s.framing_errors:
                    why = (f"the peer at {peer} answers without the hiludp session handshake "
                           f"({s.session_dropped + s.framing_errors} datagrams dropped): an old or foreign target, "
                           "see docs/protocol.md")
                else:
                    why = f"no answer from the peer at {peer} within {timeout_s:g} s (is a target running there?"
                    why += " Does it authenticate frames?)" if self.auth is not None else ")"
                raise LinkError(f"{self.channel_info}: no session agreed: {why}")
            self._pump()
            self._wait_readable(0.01)

    def _rejection(self) -> str:
        peer = f"{self._remote[0]}:{self._remote[1]}"
        if self.rejected == REJECT_KEY and self.auth is not None:
            return (f"the peer at {peer} refused our HELLO: its authentication key differs from this end's "
                    "(the same key=HEX / keyfile=PATH on both ends)")
        if self.rejected == REJECT_KEY:
            return (f"the peer at {peer} authenticates frames and this end does not: give this end its key "
                    "(key=HEX or keyfile=PATH in the link SPEC)")
        return (f"the peer at {peer} does not authenticate frames and this end does: start it with the same key "
                "(key=HEX or keyfile=PATH), or drop the key here")

    def _control_in(self, dgram: bytes) -> None:
        """A control datagram (session 0) from the peer: HELLO, ACK or a REJECT of our HELLO."""
        stats = self.link_stats
        auth = self.auth
        _, magic, kind, version, sid = CONTROL.unpack_from(dgram)
        if magic != MAGIC or version != VERSION or kind not in (HELLO, ACK, REJECT_KEY, REJECT_PLAIN) or not sid:
            stats.framing_errors += 1
            return
        if kind in (REJECT_KEY, REJECT_PLAIN):
            if sid == self._proposal:
                self.rejected = kind
            else:
                stats.session_dropped += 1
            return
        nonce = 0
        if (len(dgram) == AUTH_CONTROL_SIZE) != (auth is not None):  # authenticated on one end only
            stats.auth_failed += 1
            if kind == HELLO:
                self._control(REJECT_KEY if auth is not None else REJECT_PLAIN, sid)
            return
        if auth is not None:
            signed = dgram[:CONTROL.size + NONCE.size]
            if not secrets.compare_digest(auth.control_mac(auth.rx_dir, signed), dgram[len(signed):]):
                stats.auth_failed += 1
                if kind == HELLO:
                    self._control(REJECT_KEY, sid)
                return
            nonce = NONCE.unpack_from(dgram, CONTROL.size)[0]
        if kind == ACK:
            if sid == self._proposal:
                self._use(sid, agreed=True, nonce=nonce)
            else:
                stats.session_dropped += 1
        elif self._proposal > sid:  # a clash: the larger id wins, the peer adopts ours
            self._next_hello = 0.0
        else:
            if sid != self.session or not self.established:  # a repeated HELLO keeps the session's nonce
                self._use(sid, agreed=True, nonce=_new_session_id() if auth is not None else 0)
            self._control(ACK, sid, self.nonce)

    def _slow(self, dgram: bytes) -> None:
        """A datagram from the peer outside the agreed session: handshake, first frames or a drop."""
        stats = self.link_stats
        n = len(dgram)
        if n in (CONTROL.size, AUTH_CONTROL_SIZE) and dgram[:4] == b"\0\0\0\0":
            self._control_in(dgram)
            return
        if self.auth is not None and n >= _DATA_MIN and dgram[_LENGTH_AT] == n - _DATA_MIN:
            stats.auth_failed += 1  # a frame without the authentication trailer
        elif n < self._data_min or dgram[_LENGTH_AT] != n - self._data_min:
            stats.framing_errors += 1
        elif self._proposal and dgram[:4] == self._tx_prefix and self.auth is None:
            # the peer adopted our proposal (its ACK is late; an authenticated link needs the ACK's nonce)
            self._use(self._proposal, agreed=True)
            self._checked(dgram)
        else:
            stats.session_dropped += 1

    def _checked(self, dgram: bytes) -> None:
        """Accept a data datagram of the session whose CRC-16 matches (else `crc_errors`, dropped)."""
        body = dgram[SESSION.size:-CRC_SIZE]
        if binascii.crc_hqx(body, CRC_INIT) != int.from_bytes(dgram[-CRC_SIZE:], "big"):
            self.link_stats.crc_errors += 1
            return
        self._accept(dgram[:-CRC_SIZE], SESSION.size)

    # -- FramedBus primitives --
    def _before_seal(self) -> None:
        """An authenticated frame needs the session's MAC context: agree one first."""
        if not self.established:
            self.wait_session(AUTH_SESSION_WAIT_S)

    def _transmit(self, packet: bytes) -> None:
        if not self.session:
            self.propose()
        crc = binascii.crc_hqx(packet, CRC_INIT).to_bytes(CRC_SIZE, "big")
        dgram = self._tx_prefix + packet + crc
        try:
            self._sock.sendto(dgram, self._remote)
        except ConnectionRefusedError:  # an earlier datagram was refused: counted, this one resent
            self._refused()
            self._sock.sendto(dgram, self._remote)

    def _pump(self) -> None:
        """Read datagrams until one frame is delivered or the socket is empty (never blocks)."""
        if self._proposal and time.perf_counter() >= self._next_hello:
            self._control(HELLO, self._proposal)
            self._next_hello = time.perf_counter() + HELLO_INTERVAL_S
        recvfrom = self._sock.recvfrom
        stats = self.link_stats
        peer = self._remote
        rx = self._rx
        data_min = self._data_min
        while not rx:  # one frame per call: an empty socket costs a BlockingIOError (~2 µs)
            try:
                dgram, addr = recvfrom(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return
            except ConnectionRefusedError:  # a datagram sent earlier was refused
                self._refused()
                continue
            except OSError:  # another ICMP error reported on some platforms
                stats.framing_errors += 1
                return
            if addr != peer:
                stats.foreign_dropped += 1
            elif (dgram[:4] == self._rx_prefix and (n := len(dgram)) >= data_min
                  and dgram[_LENGTH_AT] == n - data_min):
                self._checked(dgram)
            else:
                self._slow(dgram)

    def shutdown(self) -> None:
        """Close the socket (python-can API; idempotent)."""
        if self._is_shutdown:
            return
        super().shutdown()
        self._sock.close()


__all__ = ["UdpUnicastBus", "free_udp_ports", "link_socket_drops", "parse_udp_channel", "udp_socket_drops"]
