"""SocketCAN links whose kernel receive drops are counted: python-can's `socketcan` bus with a receive buffer
sized for a burst of a run's frames (`SO_RCVBUF`) and the kernel's drop counter (`SO_RXQ_OVFL`) read on every
receive.

A CAN_RAW socket whose receive buffer is full drops what arrives, silently: the default buffer (212 992 bytes)
holds about 280 CAN FD frames, so a reader that stalls for 15 ms of a 20 kHz run with two frames a period
loses frames that show up only as a missing Command. With `SO_RXQ_OVFL` on, the kernel attaches its running
count of frames dropped for the socket to every frame queued after a drop; python-can's `capture_message` accepts
only the timestamp as ancillary data, so this bus hands it a socket view that takes the drop count off first
(`_DropCountingSocket`). `kernel_dropped()` is the larger of the last count seen and `SO_MEMINFO`'s (drops
after the last frame received show too). The C loop reads the same counter on the same socket
(src/pmsm_hil/hil/runner/c/links/loop_socketcan.c) and hands its count back.
"""

from __future__ import annotations

import select
import socket
import struct
from typing import Any

import can
from can.interfaces.socketcan.socketcan import SocketcanBus, capture_message

#: <asm-generic/socket.h> values (Python's socket module does not name them)
SO_RCVBUFFORCE = 33
SO_RXQ_OVFL = 40
SO_MEMINFO = 55
SK_MEMINFO_DROPS = 8  # index of the drop count in SO_MEMINFO's u32 array
_SK_MEMINFO_VARS = 9
#: receive-buffer bytes one CAN FD frame takes (the skb's truesize on x86-64: 212 992 bytes held 278 frames)
RCVBUF_BYTES_PER_FRAME = 768
#: frames a SocketCAN link's receive buffer holds by default (`rx_frames=` link option): 100 ms of a 20 kHz run
#: with two frames a period, the stall a loaded host may give a reader (scheduling, a garbage collection)
DEFAULT_RX_FRAMES = 4096
_OVFL = struct.Struct("=I")
_OVFL_SPACE = socket.CMSG_SPACE(_OVFL.size)


def size_receive_buffer(sock: socket.socket, frames: int) -> int:
    """Ask for a receive buffer holding `frames` CAN FD frames (SO_RCVBUFFORCE where allowed, i.e. root or
    CAP_NET_ADMIN; else SO_RCVBUF, capped by net.core.rmem_max) and return the size the kernel granted
    [bytes] (at least its minimum, a few frames)."""
    want = max(1, frames) * RCVBUF_BYTES_PER_FRAME // 2  # the kernel doubles the value for its bookkeeping
    for option in (SO_RCVBUFFORCE, socket.SO_RCVBUF):
        try:
            sock.setsockopt(socket.SOL_SOCKET, option, want)
            break
        except OSError:
            continue
    return int(sock.getsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF))


def meminfo_drops(sock: socket.socket) -> int | None:
    """The kernel's count of packets dropped for `sock` (SO_MEMINFO), None where the kernel does not say."""
    try:
        raw = sock.getsockopt(socket.SOL_SOCKET, SO_MEMINFO, 4 * _SK_MEMINFO_VARS)
    except OSError:
        return None
    if len(raw) < 4 * (SK_MEMINFO_DROPS + 1):
        return None
    return int(struct.unpack_from("=I", raw, 4 * SK_MEMINFO_DROPS)[0])


class _DropCountingSocket:
    """The bus's socket as `capture_message` reads it: `recvmsg` asks for room for the drop count too, keeps
    the count and returns the other ancillary items."""

    __slots__ = ("dropped", "sock")

    def __init__(self, sock: socket.socket) -> None:
        self.sock = sock
        self.dropped = 0

    def recvmsg(self, bufsize: int, ancbufsize: int = 0, flags: int = 0) -> tuple[bytes, list[Any], int, Any]:
        data, ancillary, msg_flags, addr = self.sock.recvmsg(bufsize, ancbufsize + _OVFL_SPACE, flags)
        kept = []
        for level, kind, payload in ancillary:
            if level == socket.SOL_SOCKET and kind == SO_RXQ_OVFL and len(payload) >= _OVFL.size:
                self.dropped = max(self.dropped, int(_OVFL.unpack_from(payload)[0]))
            else:
                kept.append((level, kind, payload))
        return data, kept, msg_flags, addr


class SocketcanLinkBus(SocketcanBus):
    """python-can's SocketCAN bus with the receive buffer sized for `rx_frames` frames and the kernel's
    receive drops counted (`kernel_dropped`); `rcvbuf_bytes`: the buffer the kernel granted [bytes]."""

    def __init__(self, channel: str = "", *, rx_frames: int = DEFAULT_RX_FRAMES, **kwargs: Any) -> None:
        super().__init__(channel=channel, **kwargs)
        try:
            frames = int(rx_frames)
        except (TypeError, ValueError) as exc:
            self.socket.close()
            raise ValueError(f"link option rx_frames must be an integer, got {rx_frames!r}") from exc
        if frames < 1:
            self.socket.close()
            raise ValueError(f"link option rx_frames must be at least 1, got {frames}")
        self.rcvbuf_bytes = size_receive_buffer(self.socket, frames)
        self.socket.setsockopt(socket.SOL_SOCKET, SO_RXQ_OVFL, 1)
        self._counting = _DropCountingSocket(self.socket)

    def note_kernel_dropped(self, count: int) -> None:
        """A count of this socket's kernel drops read elsewhere (the C loop on the same socket)."""
        self._counting.dropped = max(self._counting.dropped, int(count))

    def kernel_dropped(self) -> int:
        """Frames the kernel dropped for this socket so far (its receive buffer full)."""
        seen = self._counting.dropped
        if self.socket.fileno() < 0:
            return seen
        later = meminfo_drops(self.socket)
        return seen if later is None else max(seen, later)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        try:
            ready, _, _ = select.select([self.socket], [], [], timeout)
        except OSError as error:
            raise can.CanOperationError(f"Failed to receive: {error.strerror}", error.errno) from error
        if not ready:
            return None, self._is_filtered
        msg = capture_message(self._counting, self.channel == "")  # type: ignore[arg-type]
        if msg is not None and not msg.channel and self.channel:
            msg.channel = self.channel
        return msg, self._is_filtered


__all__ = ["DEFAULT_RX_FRAMES", "SocketcanLinkBus", "meminfo_drops", "size_receive_buffer"]
