"""Link-level counters and the per-sender link sequence check."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(slots=True)
class LinkStats:
    """Counters of one link end (never reset implicitly).

    dropped/duplicate/out_of_order come from the 8-bit link sequence number of the UDP and serial
    framings (python-can buses such as virtual or SocketCAN have none: they stay 0 there)."""

    frames_tx: int = 0
    frames_rx: int = 0
    crc_errors: int = 0
    framing_errors: int = 0
    dropped: int = 0
    duplicate: int = 0
    out_of_order: int = 0
    send_errors: int = 0
    ignored: int = 0  # remote/error frames or extended ids seen by the generic path
    foreign_dropped: int = 0  # UDP datagrams from an address other than the configured peer
    session_dropped: int = 0  # UDP datagrams from the peer outside the agreed session
    auth_failed: int = 0  # authenticated links: frames (and UDP control datagrams) whose MAC failed or was missing
    auth_replayed: int = 0  # authenticated links: frames with a valid MAC but a stale freshness value (a replay)

    def as_dict(self) -> dict[str, int]:
        """Counters by name."""
        return {name: getattr(self, name) for name in self.__slots__}


class SeqTracker:
    """Checks the 8-bit link sequence number of one sender; updates `stats`; True = accept."""

    __slots__ = ("_last", "_stats")

    def __init__(self, stats: LinkStats) -> None:
        self._stats = stats
        self._last = -1

    @property
    def last(self) -> int:
        """The last sequence number accepted (-1: none yet); settable for a native loop handing the link back."""
        return self._last

    @last.setter
    def last(self, seq: int) -> None:
        self._last = seq

    def accept(self, seq: int) -> bool:
        """Count gaps (dropped), repeats (duplicate) and late frames (out_of_order, still delivered)."""
        last = self._last
        if last < 0:
            self._last = seq
            return True
        d = (seq - last) & 0xFF
        if d == 1:
            self._last = seq
            return True
        if d == 0:
            self._stats.duplicate += 1
            return False
        if d < 128:
            self._stats.dropped += d - 1
            self._last = seq
            return True
        self._stats.out_of_order += 1
        return True
