"""Reassembly of sequence-numbered messages from their frame parts, with error counters.

A message of kind K is sent as parts 0..n-1, each carrying its sequence number (16 bits, or only the
low 8 bits for MeasB). The assembler delivers a message when all parts of one seq arrived, and counts:
duplicate (same seq again), stale (seq behind the last delivered one), mixed_seq (a newer seq arrived
before the held parts completed: they are dropped), out_of_order (parts assembled but not received
in sending order).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

STALE_WINDOW = 1024  # a seq up to this far behind the last delivered one is stale; further = restart


@dataclass(slots=True)
class DecodeStats:
    """Counters of a FrameDecoder (never reset implicitly)."""

    frames: int = 0
    messages: int = 0
    unknown_id: int = 0
    bad_length: int = 0
    bad_value: int = 0
    stale: int = 0
    duplicate: int = 0
    out_of_order: int = 0
    mixed_seq: int = 0

    def as_dict(self) -> dict[str, int]:
        """Counters by name."""
        return {name: getattr(self, name) for name in self.__slots__}


class Assembler:
    """Collects the parts of one message kind; `add` returns the raw parts when complete."""

    __slots__ = ("_held_mask", "_held_seq", "_last", "_n", "_ordered", "_parts", "_stats", "_unordered")

    def __init__(self, n_parts: int, stats: DecodeStats, *, ordered: bool = True) -> None:
        """`ordered`: drop messages whose seq is not newer than the last one delivered (a target's view of
        the host's Measurements). With `ordered=False` every complete message is delivered and a part with
        another seq than the held ones replaces them (the host checks each Command's seq itself: a corrupted
        future seq must not block the genuine replies that follow)."""
        self._n = n_parts
        self._stats = stats
        self._ordered = ordered
        self._parts: list[Any] = [None] * n_parts
        self._held_seq = -1  # seq of the held parts, -1 when none held
        self._held_mask = 0
        self._last = -1  # last delivered full seq, -1 before the first
        self._unordered = False

    def add(self, part: int, seq: int, mask: int, raw: Any) -> list[Any] | None:
        """Offer part `part` with sequence `seq` (known to `mask` bits: 0xFFFF or 0xFF)."""
        stats = self._stats
        if self._last >= 0 and self._ordered:
            d = (seq - self._last) & mask
            if d == 0:
                stats.duplicate += 1
                return None
            if d >= mask + 1 - min(STALE_WINDOW, (mask + 1) >> 1):
                stats.stale += 1
                return None
        if self._held_seq >= 0:
            m = mask & self._held_mask
            d = (seq - self._held_seq) & m
            if d == 0:
                if self._parts[part] is not None:
                    stats.duplicate += 1
                    return None
            elif d <= (m >> 1) or not self._ordered:
                stats.mixed_seq += 1
                self._clear()
            else:
                stats.stale += 1
                return None
        parts = self._parts
        if self._held_seq < 0 or mask > self._held_mask:
            self._held_seq = seq
            self._held_mask = mask
        if not self._unordered:
            for later in range(part + 1, self._n):
                if parts[later] is not None:
                    self._unordered = True
                    break
        parts[part] = raw
        for p in parts:
            if p is None:
                return None
        if self._unordered:
            stats.out_of_order += 1
        self._last = self._held_seq
        done = parts
        self._parts = [None] * self._n
        self._held_seq = -1
        self._held_mask = 0
        self._unordered = False
        return done

    def restart(self) -> None:
        """Forget the last delivered seq and any held parts: the next message starts a new sequence."""
        self._clear()
        self._last = -1

    def _clear(self) -> None:
        self._parts = [None] * self._n
        self._held_seq = -1
        self._held_mask = 0
        self._unordered = False
