"""python-can interface `hilserial`: frames over a byte stream with COBS framing and CRC-16.

channel: a serial port (/dev/ttyACM0, /dev/pts/N), any pyserial URL (socket://host:port, loop://),
or "fd:N" for an already-open descriptor (e.g. a pty master from os.openpty()).
Packet: COBS(header + payload + CRC-16/CCITT-FALSE big-endian) followed by 0x00; see docs/protocol.md.
"""

from __future__ import annotations

import contextlib
import os
from typing import Any

import can
import serial

from pmsm_hil.protocol.links.cobs import Deframer, encode_packet
from pmsm_hil.protocol.links.framed_bus import FramedBus

DEFAULT_BAUDRATE = 115200
READ_CHUNK = 4096


class _FdPort:
    """Minimal pyserial-like port over a raw non-blocking descriptor (pty master)."""

    def __init__(self, fd: int) -> None:
        self._fd = fd
        os.set_blocking(fd, False)

    def fileno(self) -> int:
        return self._fd

    def write(self, data: bytes) -> int:
        view = memoryview(data)
        while view:
            try:
                n = os.write(self._fd, view)
            except BlockingIOError:
                continue  # output buffer full: busy-retry (a pty drains as the peer reads)
            view = view[n:]
        return len(data)

    def close(self) -> None:
        os.close(self._fd)


class CobsSerialBus(FramedBus):
    """Frames over a serial line (real UART, USB CDC, pty, TCP socket)."""

    def __init__(
        self, channel: Any = None, *, baudrate: int = DEFAULT_BAUDRATE, fd: bool = True, **kwargs: Any
    ) -> None:
        if channel is None:
            raise can.CanInitializationError("hilserial needs channel=PORT, URL or fd:N")
        chan = str(channel)
        self._port: Any
        self._raw_fd = -1
        try:
            if chan.startswith("fd:"):
                self._port = _FdPort(int(chan[3:]))
                self._raw_fd = self._port.fileno()
            else:
                self._port = serial.serial_for_url(chan, baudrate=int(baudrate), timeout=0, write_timeout=None)
                try:
                    self._raw_fd = self._port.fileno() if isinstance(self._port, serial.Serial) else -1
                except (AttributeError, NotImplementedError, serial.SerialException):
                    self._raw_fd = -1
        except (ValueError, OSError, serial.SerialException) as exc:
            raise can.CanInitializationError(f"hilserial: cannot open {chan!r}: {exc}") from exc
        self.channel_info = f"hilserial {chan}"
        super().__init__(channel=channel, fd=fd, **kwargs)
        self._deframer = Deframer(self.link_stats, self._accept, self.trailer)

    def fileno(self) -> int:
        """Descriptor of the port, or -1 when the transport has none (socket:// URLs)."""
        if self._raw_fd >= 0:
            return self._raw_fd
        raise NotImplementedError("no descriptor for this serial transport")

    @property
    def deframer(self) -> Deframer:
        """The receiver's deframer (a native loop reading the port for a run takes its state over)."""
        return self._deframer

    def _encode(self, body: bytes) -> bytes:
        return encode_packet(body)

    def _transmit(self, packet: bytes) -> None:
        self._port.write(packet)

    def _pump(self) -> None:
        if self._raw_fd >= 0:
            while True:
                try:
                    chunk = os.read(self._raw_fd, READ_CHUNK)
                except (BlockingIOError, InterruptedError):
                    return
                except OSError:  # pty peer closed (EIO)
                    return
                if not chunk:
                    return
                self._deframer.feed(chunk)
        else:
            try:
                chunk = self._port.read(READ_CHUNK)
            except (OSError, serial.SerialException):
                return
            if chunk:
                self._deframer.feed(chunk)

    def shutdown(self) -> None:
        """Close the port (python-can API; idempotent)."""
        if self._is_shutdown:
            return
        super().shutdown()
        with contextlib.suppress(OSError):
            self._port.close()
