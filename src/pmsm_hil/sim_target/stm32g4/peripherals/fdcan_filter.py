"""Acceptance filtering of the STM32G4 FDCAN (RM0440 "Acceptance filtering"): the standard and extended filter
lists in message RAM, scanned from element 0, the first match deciding; the global filter (RXGFC) for remote frames
and frames no element matched."""

from __future__ import annotations

from typing import NamedTuple

# Filter element configuration (SFEC / EFEC)
EC_DISABLE = 0b000
EC_FIFO0 = 0b001
EC_FIFO1 = 0b010
EC_REJECT = 0b011
EC_PRIORITY = 0b100
EC_PRIORITY_FIFO0 = 0b101
EC_PRIORITY_FIFO1 = 0b110
# Filter types (SFT / EFT)
FT_RANGE = 0b00
FT_DUAL = 0b01
FT_CLASSIC = 0b10
FT_RANGE_NO_MASK = 0b11  # extended list only; in the standard list 0b11 disables the element


class Decision(NamedTuple):
    """Where a received frame goes: `fifo` 0 or 1, None when rejected; `filter_index` None for a frame accepted
    by the global filter (no element matched); `priority` for a high-priority match (HPMS/IR.HPM)."""

    fifo: int | None
    filter_index: int | None
    priority: bool


def _action(config: int, index: int) -> Decision | None:
    """The decision of a matching element with configuration `config` (None: the element is disabled)."""
    if config == EC_DISABLE or config == 0b111:
        return None
    if config == EC_REJECT:
        return Decision(None, index, False)
    if config == EC_PRIORITY:
        return Decision(None, index, True)
    fifo = 0 if config in (EC_FIFO0, EC_PRIORITY_FIFO0) else 1
    return Decision(fifo, index, config in (EC_PRIORITY_FIFO0, EC_PRIORITY_FIFO1))


def match_standard(words: list[int], can_id: int) -> Decision | None:
    """The first standard filter element (one word each: SFT 31:30, SFEC 29:27, SFID1 26:16, SFID2 10:0) that
    matches the 11-bit `can_id` and is enabled; None when none does."""
    for index, word in enumerate(words):
        sft = (word >> 30) & 0x3
        sfec = (word >> 27) & 0x7
        id1 = (word >> 16) & 0x7FF
        id2 = word & 0x7FF
        if sfec == EC_DISABLE or sft == 0b11:
            continue
        if sft == FT_RANGE:
            hit = id1 <= can_id <= id2
        elif sft == FT_DUAL:
            hit = can_id in (id1, id2)
        else:
            hit = (can_id & id2) == (id1 & id2)
        if hit:
            decision = _action(sfec, index)
            if decision is not None:
                return decision
    return None


def match_extended(pairs: list[tuple[int, int]], can_id: int, xidam: int) -> Decision | None:
    """The first extended filter element (F0: EFEC 31:29, EFID1 28:0; F1: EFT 31:30, EFID2 28:0) that matches the
    29-bit `can_id`; the id is ANDed with XIDAM first, except for EFT 11 (range without mask)."""
    masked = can_id & xidam
    for index, (f0, f1) in enumerate(pairs):
        efec = (f0 >> 29) & 0x7
        id1 = f0 & 0x1FFF_FFFF
        eft = (f1 >> 30) & 0x3
        id2 = f1 & 0x1FFF_FFFF
        if efec == EC_DISABLE:
            continue
        if eft == FT_RANGE:
            hit = id1 <= masked <= id2
        elif eft == FT_DUAL:
            hit = masked in (id1, id2)
        elif eft == FT_CLASSIC:
            hit = (masked & id2) == (id1 & id2)
        else:
            hit = id1 <= can_id <= id2
        if hit:
            decision = _action(efec, index)
            if decision is not None:
                return decision
    return None


def global_decision(rxgfc: int, extended: bool, remote: bool) -> Decision | None:
    """What RXGFC says before the lists (a rejected remote frame: a Decision to nowhere) or None to scan them."""
    if remote and rxgfc & (0b01 if extended else 0b10):
        return Decision(None, None, False)
    return None


def non_matching(rxgfc: int, extended: bool) -> Decision:
    """The global filter's decision for a frame no element matched (ANFE 3:2 / ANFS 5:4: 00 FIFO 0, 01 FIFO 1,
    1x reject)."""
    anf = (rxgfc >> (2 if extended else 4)) & 0x3
    return Decision(anf if anf < 2 else None, None, False)
