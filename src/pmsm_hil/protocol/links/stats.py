"""Link-level counters (the C links keep them as nl_link_stats_t, same names)."""

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
        return {name: getattr(self, name) for name in LinkStats.__slots__}
