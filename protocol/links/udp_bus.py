"""python-can interface `hiludp`: unicast UDP, one frame per datagram (header from `wire`).

channel: "LOCALPORT:REMOTEPORT[@HOST]" (HOST default 127.0.0.1). Non-blocking socket; the Link
wrapper busy-polls `poll_frame`. Example: can.Bus(interface="hiludp", channel="47310:47311").
"""

from __future__ import annotations

import socket
from typing import Any

import can
from pmsm_hil.protocol.links.framed_bus import FramedBus
from pmsm_hil.protocol.links.wire import HEADER, HEADER_SIZE

DEFAULT_HOST = "127.0.0.1"
MAX_DATAGRAM = 2048


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


class UdpUnicastBus(FramedBus):
    """Point-to-point UDP bus (both ends on one host or across a network)."""

    def __init__(self, channel: Any = None, *, fd: bool = True, **kwargs: Any) -> None:
        if channel is None:
            raise can.CanInitializationError("hiludp needs channel='LOCALPORT:REMOTEPORT[@HOST]'")
        try:
            local, remote, host = parse_udp_channel(channel)
        except ValueError as exc:
            raise can.CanInitializationError(str(exc)) from exc
        self._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self._sock.bind((host if host in ("127.0.0.1", "localhost") else "", local))
        except OSError as exc:
            self._sock.close()
            raise can.CanInitializationError(f"hiludp: cannot bind UDP port {local}: {exc}") from exc
        self._sock.setblocking(False)
        self._remote = (host, remote)
        self.local_port = self._sock.getsockname()[1]
        self.channel_info = f"hiludp {self.local_port}->{host}:{remote}"
        super().__init__(channel=channel, fd=fd, **kwargs)

    def fileno(self) -> int:
        """Socket descriptor (for select-based python-can notifiers)."""
        return self._sock.fileno()

    def _transmit(self, packet: bytes) -> None:
        self._sock.sendto(packet, self._remote)

    def _pump(self) -> None:
        recv = self._sock.recv
        stats = self.link_stats
        while True:
            try:
                dgram = recv(MAX_DATAGRAM)
            except (BlockingIOError, InterruptedError):
                return
            except OSError:  # e.g. ICMP port unreachable reported on some platforms
                stats.framing_errors += 1
                return
            if len(dgram) < HEADER_SIZE or HEADER.unpack_from(dgram)[3] != len(dgram) - HEADER_SIZE:
                stats.framing_errors += 1
                continue
            self._accept(dgram)

    def shutdown(self) -> None:
        """Close the socket (python-can API; idempotent)."""
        if self._is_shutdown:
            return
        super().shutdown()
        self._sock.close()
