"""The frame tuple moved by links: 11-bit identifier, payload, CAN FD flag."""

from __future__ import annotations

from typing import NamedTuple


class Frame(NamedTuple):
    """One CAN / CAN FD frame (classic: ≤ 8 bytes; FD: a valid FD length ≤ 64 bytes)."""

    arbitration_id: int
    data: bytes
    is_fd: bool = False
