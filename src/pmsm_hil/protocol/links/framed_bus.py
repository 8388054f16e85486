"""Common base of the UDP and serial python-can plugins: header framing, link sequence numbers,
statistics, and a fast path (`send_frame` / `poll_frame`) that skips can.Message construction."""

from __future__ import annotations

import select
import time
from collections import deque
from typing import Any

import can
from can import CanProtocol

from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links.auth import AUTH_FAILED, AUTH_OK, TRAILER, FrameAuth
from pmsm_hil.protocol.links.stats import LinkStats, SeqTracker
from pmsm_hil.protocol.links.wire import (
    FLAG_BRS,
    FLAG_ESI,
    FLAG_EXTENDED,
    FLAG_FD,
    FLAG_REMOTE,
    HEADER,
    HEADER_SIZE,
    pack_frame,
    valid_payload_length,
)


class FramedBus(can.BusABC):
    """python-can bus moving header-framed frames; subclasses implement `_transmit`, `_pump`, `fileno`."""

    def __init__(self, channel: Any, *, fd: bool = True, auth_key: bytes | None = None,
                 auth_role: str = "host", **kwargs: Any) -> None:
        super().__init__(channel=channel, **kwargs)
        self.link_stats = LinkStats()
        #: authenticated frames (src/pmsm_hil/protocol/links/auth.py) with this key, None: off
        self.auth: FrameAuth | None = None if auth_key is None else FrameAuth(
            auth_key, "target" if auth_role == "target" else "host")
        #: bytes after the payload of every frame (the authentication trailer, 0: none)
        self.trailer = TRAILER if self.auth is not None else 0
        self.fd = bool(fd)
        self._can_protocol = CanProtocol.CAN_FD if self.fd else CanProtocol.CAN_20
        self._tx_seq = 0
        self._rx: deque[tuple[int, bytes, int]] = deque()
        self._tracker = SeqTracker(self.link_stats)

    # -- subclass primitives --
    def _transmit(self, packet: bytes) -> None:
        raise NotImplementedError

    def _pump(self) -> None:
        """Read everything available without blocking; call `_accept` per received frame body."""
        raise NotImplementedError

    def _encode(self, body: bytes) -> bytes:
        return body

    # -- shared --
    @property
    def link_seq(self) -> tuple[int, int]:
        """(next link sequence number sent, last one received or -1): what a native loop taking the socket or
        port over for a run continues from (`resume_link_seq` hands them back)."""
        return self._tx_seq, self._tracker.last

    def resume_link_seq(self, tx_seq: int, rx_last: int) -> None:
        """Continue from the link sequence numbers a native loop used on this socket or port."""
        self._tx_seq = tx_seq & 0xFF
        self._tracker.last = rx_last

    def _before_seal(self) -> None:
        """What must hold before a frame is authenticated (UDP: an agreed session, its MAC context)."""

    def _accept(self, packet: bytes, offset: int = 0) -> None:
        """A header+payload (+ the authentication trailer) whose length field matches arrived at `offset` of
        `packet`; one that fails authentication is dropped (auth_failed / auth_replayed); a payload length that is
        not a valid classic (≤ 8) or FD length is a framing error."""
        if self.auth is not None:
            verdict = self.auth.open(memoryview(packet)[offset:])
            if verdict != AUTH_OK:
                if verdict == AUTH_FAILED:
                    self.link_stats.auth_failed += 1
                else:
                    self.link_stats.auth_replayed += 1
                return
        arb, flags, seq, length = HEADER.unpack_from(packet, offset)
        if not valid_payload_length(length, bool(flags & FLAG_FD)):
            self.link_stats.framing_errors += 1
        elif self._tracker.accept(seq):
            self.link_stats.frames_rx += 1
            self._rx.append((arb, packet[offset + HEADER_SIZE:offset + HEADER_SIZE + length], flags))

    def send_frame(self, arbitration_id: int, data: bytes, is_fd: bool, flags: int = 0) -> None:
        """Fast path send; raises can.CanOperationError on an invalid length or an I/O error."""
        if not valid_payload_length(len(data), is_fd) or (is_fd and not self.fd):
            self.link_stats.send_errors += 1
            raise can.CanOperationError(f"payload length {len(data)} invalid for {'FD' if is_fd else 'classic'} frame")
        if is_fd:
            flags |= FLAG_FD | FLAG_BRS
        body = pack_frame(arbitration_id, data, flags, self._tx_seq)
        if self.auth is not None:
            self._before_seal()
            body = self.auth.seal(body)
        self._tx_seq = (self._tx_seq + 1) & 0xFF
        try:
            self._transmit(self._encode(body))
        except OSError as exc:
            self.link_stats.send_errors += 1
            raise can.CanOperationError(f"{type(self).__name__} send failed: {exc}") from exc
        self.link_stats.frames_tx += 1

    def poll_raw(self) -> tuple[int, bytes, int] | None:
        """Fast path receive: (id, payload, flags) or None, never blocks."""
        if not self._rx:
            self._pump()
            if not self._rx:
                return None
        return self._rx.popleft()

    def poll_frame(self) -> Frame | None:
        """Fast path receive of an 11-bit data frame; other frames are counted as ignored."""
        while True:
            item = self.poll_raw()
            if item is None:
                return None
            arb, data, flags = item
            if flags & (FLAG_EXTENDED | FLAG_REMOTE):
                self.link_stats.ignored += 1
                continue
            return Frame(arb, data, bool(flags & FLAG_FD))

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """python-can API."""
        flags = (FLAG_EXTENDED if msg.is_extended_id else 0) | (FLAG_REMOTE if msg.is_remote_frame else 0)
        flags |= FLAG_ESI if msg.error_state_indicator else 0
        data = bytes(msg.data) if not msg.is_remote_frame else bytes(msg.dlc)  # a remote frame: DLC zero bytes
        if msg.is_fd and not msg.bitrate_switch:
            flags &= ~FLAG_BRS
        self.send_frame(msg.arbitration_id, data, msg.is_fd, flags)

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        item = self.poll_raw()
        if item is None and timeout != 0:
            deadline = None if timeout is None else time.monotonic() + timeout
            while item is None:
                left = None if deadline is None else max(0.0, deadline - time.monotonic())
                self._wait_readable(left)
                item = self.poll_raw()
                if left == 0.0:
                    break
        if item is None:
            return None, False
        arb, data, flags = item
        msg = can.Message(
            timestamp=time.time(),
            arbitration_id=arb,
            data=None if flags & FLAG_REMOTE else data,
            is_fd=bool(flags & FLAG_FD),
            bitrate_switch=bool(flags & FLAG_BRS),
            error_state_indicator=bool(flags & FLAG_ESI),
            is_extended_id=bool(flags & FLAG_EXTENDED),
            is_remote_frame=bool(flags & FLAG_REMOTE),
            dlc=len(data),
            channel=self.channel_info,
            is_rx=True,
        )
        return msg, False

    def _wait_readable(self, timeout: float | None) -> None:
        """Blocking wait for tools (python-can recv with a timeout); the Link fast path never calls it."""
        try:
            select.select([self.fileno()], [], [], timeout)
        except (OSError, NotImplementedError, ValueError):
            time.sleep(min(timeout, 0.001) if timeout is not None else 0.001)
