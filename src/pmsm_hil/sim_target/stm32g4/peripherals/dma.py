"""DMA1 and DMA2 of the STM32G474 (RM0440 "Direct memory access controller"): 8 channels each (6 on the G431) at
0x40020000 and 0x40020400, one interrupt line per channel (DMA1_Channel1..7: IRQ 11..17, DMA1_Channel8: 96;
DMA2_Channel1..5: 56..60, DMA2_Channel6..8: 97..99).

A peripheral-to-memory or memory-to-peripheral channel moves one item per request that DMAMUX1 routes to it
(`Dma.transfer`); a memory-to-memory channel (MEM2MEM) runs to completion when it is enabled. Each item is read and
written through `BusMaster.access`, the path the CPU's loads and stores take, so a DMA read of a data register has
the side effects of a CPU read (an ADC's DR read clears EOC). A source wider than the destination is truncated to
its low bytes, a narrower one zero-extended (RM0440 "programmable data width" table).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import cast

from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardBus, BoardError, BusMaster, Peripheral, register

ISR, IFCR = 0x00, 0x04
#: first channel's CCR, and the stride between channels (CCR, CNDTR, CPAR, CMAR, one reserved word)
CHANNEL_BASE, CHANNEL_STRIDE = 0x08, 0x14
CCR, CNDTR, CPAR, CMAR = 0x0, 0x4, 0x8, 0xC

# CCR bits
EN, TCIE, HTIE, TEIE, DIR, CIRC, PINC, MINC = (1 << b for b in range(8))
PSIZE_SHIFT, MSIZE_SHIFT, PL_SHIFT = 8, 10, 12
MEM2MEM = 1 << 14
CCR_MASK = 0x7FFF
#: CCR bits that stay writable while the channel is enabled (the enable and the interrupt enables; RM0440 makes
#: the configuration bits read-only while EN is set)
CCR_LIVE = EN | TCIE | HTIE | TEIE

# ISR flags of one channel, at bit 4 * (channel - 1)
GIF, TCIF, HTIF, TEIF = 1, 2, 4, 8
#: data size field value -> bytes (3 is reserved)
SIZES = {0: 1, 1: 2, 2: 4}


@dataclass
class Channel:
    """One DMA channel: its registers and the transfer in progress (the addresses and count latched at enable)."""

    ccr: int = 0
    cndtr: int = 0
    cpar: int = 0
    cmar: int = 0
    flags: int = 0
    #: the count latched when the channel was enabled (the reload of circular mode); CNDTR counts the items left
    count: int = 0
    par: int = 0
    mar: int = 0
    line_up: bool = False

    @property
    def enabled(self) -> bool:
        return bool(self.ccr & EN)


#: parts whose DMA controllers have 6 channels (and DMAMUX1 12 channels), by name prefix (RM0440 "DMA
#: implementation": category 2 devices); the others have 8
SIX_CHANNEL_PARTS = ("stm32g431", "stm32g441")


def channel_count(bus: BoardBus) -> int:
    """The channels of each DMA controller of the board's part (a board without a part: 8, the G474's)."""
    name = str(getattr(getattr(bus, "part", None), "name", "")).lower()
    return 6 if name.startswith(SIX_CHANNEL_PARTS) else 8


class Dma(Peripheral):
    """One DMA controller; the subclasses give its name, address and interrupt lines."""

    size = 0x400
    irq_lines: tuple[int, ...] = ()

    def reset(self) -> None:
        self.channels = [Channel() for _ in self.irq_lines[:channel_count(self.bus)]]
        #: configuration writes the chip ignored because the channel was enabled (count)
        self.ignored_writes = 0
        #: items moved, all channels together (count)
        self.transfers = 0

    # ----- the register interface
    def _locate(self, offset: int, access: str) -> tuple[int, int]:
        """(channel index, register offset in the channel) of a channel register; BoardError for any other."""
        index, reg = divmod(offset - CHANNEL_BASE, CHANNEL_STRIDE)
        if offset < CHANNEL_BASE or index >= len(self.channels) or reg >= 0x10 or offset & 3:
            raise BoardError(f"{access} of {self.name} at offset {offset:#05x} ({self.base + offset:#010x}), which "
                             "the virtual board does not model (ISR, IFCR, CCRx, CNDTRx, CPARx, CMARx, word-aligned)")
        return index, reg

    def read(self, offset: int, size: int, now: int) -> int:
        del size, now
        if offset == ISR:
            return self._isr()
        if offset == IFCR:
            return 0
        index, reg = self._locate(offset, "read")
        ch = self.channels[index]
        if reg == CCR:
            return ch.ccr
        if reg == CNDTR:
            return ch.cndtr
        return ch.cpar if reg == CPAR else ch.cmar

    def write(self, offset: int, size: int, value: int, now: int) -> None:
        del size
        if offset == ISR:
            return  # read-only
        if offset == IFCR:
            self._clear_flags(value)
            return
        index, reg = self._locate(offset, "write")
        ch = self.channels[index]
        if reg == CCR:
            self._write_ccr(index, value & CCR_MASK, now)
        elif ch.enabled:
            self.ignored_writes += 1
        elif reg == CNDTR:
            ch.cndtr = value & 0xFFFF
        elif reg == CPAR:
            ch.cpar = value & 0xFFFF_FFFF
        else:
            ch.cmar = value & 0xFFFF_FFFF

    def _isr(self) -> int:
        return sum(ch.flags << (4 * i) for i, ch in enumerate(self.channels))

    def _clear_flags(self, value: int) -> None:
        for i, ch in enumerate(self.channels):
            bits = (value >> (4 * i)) & 0xF
            if bits & GIF:
                bits = TCIF | HTIF | TEIF
            if bits:
                self._set_flags(i, ch.flags & ~bits & (TCIF | HTIF | TEIF))

    def _write_ccr(self, index: int, value: int, now: int) -> None:
        ch = self.channels[index]
        if ch.enabled and (value ^ ch.ccr) & ~CCR_LIVE & CCR_MASK:
            self.ignored_writes += 1
            value = (ch.ccr & ~CCR_LIVE) | (value & CCR_LIVE)
        starting = not ch.enabled and value & EN
        if starting:
            self._check_sizes(index, value)
        ch.ccr = value
        if starting:
            ch.count = ch.cndtr
            ch.par, ch.mar = ch.cpar, ch.cmar
            if ch.ccr & MEM2MEM:
                while ch.cndtr and ch.enabled:
                    self._move(index, now)
        self._update_line(index)

    def _check_sizes(self, index: int, ccr: int) -> None:
        for field, shift in (("PSIZE", PSIZE_SHIFT), ("MSIZE", MSIZE_SHIFT)):
            if (ccr >> shift) & 3 not in SIZES:
                raise BoardError(f"{self.name} CCR{index + 1}: {field} = 3 is reserved (RM0440)")

    # ----- transfers
    def transfer(self, channel: int, now: int) -> bool:
        """A request on `channel` (1-based) at cycle `now`: move one item; False when the channel cannot serve it
        (disabled, memory-to-memory, or its count exhausted outside circular mode)."""
        index = channel - 1
        if not 0 <= index < len(self.channels):
            raise BoardError(f"{self.name} has no channel {channel}")
        ch = self.channels[index]
        if not ch.enabled or ch.ccr & MEM2MEM or ch.cndtr == 0:
            return False
        self._move(index, now)
        self._update_line(index)
        return True

    def _move(self, index: int, now: int) -> None:
        """One item from source to destination, the addresses stepped, the count down, HT/TC raised."""
        ch = self.channels[index]
        if not hasattr(self.bus, "access"):
            raise BoardError(f"{self.name}: the board gives bus masters no access to its address space "
                             "(BusMaster.access)")
        bus = cast(BusMaster, self.bus)
        psize = SIZES[(ch.ccr >> PSIZE_SHIFT) & 3]
        msize = SIZES[(ch.ccr >> MSIZE_SHIFT) & 3]
        if ch.ccr & DIR:
            src, src_size, dst, dst_size = ch.mar, msize, ch.par, psize
        else:
            src, src_size, dst, dst_size = ch.par, psize, ch.mar, msize
        try:
            data = bus.access(src, src_size, now=now) & ((1 << (8 * src_size)) - 1)
            bus.access(dst, dst_size, data & ((1 << (8 * dst_size)) - 1), now=now)
        except BoardError as exc:
            raise BoardError(f"{self.name} channel {index + 1} ({src:#010x} -> {dst:#010x}): {exc}") from exc
        self.transfers += 1
        if ch.ccr & PINC:
            ch.par = (ch.par + psize) & 0xFFFF_FFFF
        if ch.ccr & MINC:
            ch.mar = (ch.mar + msize) & 0xFFFF_FFFF
        ch.cndtr -= 1
        flags = ch.flags
        if ch.cndtr == ch.count // 2 and ch.count >= 2:
            flags |= HTIF
        if ch.cndtr == 0:
            flags |= TCIF
            if ch.ccr & CIRC and not ch.ccr & MEM2MEM:
                ch.cndtr = ch.count
                ch.par, ch.mar = ch.cpar, ch.cmar
        ch.flags = flags | (GIF if flags & (TCIF | HTIF | TEIF) else 0)

    def _set_flags(self, index: int, flags: int) -> None:
        ch = self.channels[index]
        ch.flags = flags | (GIF if flags else 0)
        self._update_line(index)

    def _update_line(self, index: int) -> None:
        """Raise or withdraw the channel's interrupt line from its flags and enables."""
        ch = self.channels[index]
        up = bool(ch.flags & ((TCIF if ch.ccr & TCIE else 0) | (HTIF if ch.ccr & HTIE else 0)
                              | (TEIF if ch.ccr & TEIE else 0)))
        if up and not ch.line_up:
            self.bus.set_pending(self.irq_lines[index])
        elif ch.line_up and not up:
            self.bus.clear_pending(self.irq_lines[index])
        ch.line_up = up


@register("DMA1")
class Dma1(Dma):
    """DMA1: channels 1..8, DMAMUX1 channels 0..7."""

    base = 0x4002_0000
    irq_lines = (11, 12, 13, 14, 15, 16, 17, 96)


@register("DMA2")
class Dma2(Dma):
    """DMA2: channels 1..8, DMAMUX1 channels 8..15."""

    base = 0x4002_0400
    irq_lines = (56, 57, 58, 59, 60, 97, 98, 99)


__all__ = ["Channel", "Dma", "Dma1", "Dma2", "channel_count"]
