"""Helpers shared by the register-file models: a named register map with reset values, and the error for an
offset a model does not implement."""

from __future__ import annotations

from typing import ClassVar

from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError, Peripheral


def unknown_register(p: Peripheral, offset: int, access: str) -> BoardError:
    """The one-line error for an offset of `p` the model does not implement."""
    return BoardError(f"{access} of {p.name} register at offset {offset:#05x} ({p.base + offset:#010x}), which the "
                      "virtual board does not model")


def merge(old: int, offset: int, size: int, value: int) -> int:
    """`old` with the `size` bytes at byte `offset & 3` replaced by `value` (byte and halfword stores)."""
    if size == 4:
        return value & 0xFFFF_FFFF
    shift = 8 * (offset & 3)
    mask = ((1 << (8 * size)) - 1) << shift
    return (old & ~mask) | ((value << shift) & mask)


def lane(word: int, offset: int, size: int) -> int:
    """The `size` bytes of `word` at byte `offset & 3` (byte and halfword loads)."""
    if size == 4:
        return word
    return (word >> (8 * (offset & 3))) & ((1 << (8 * size)) - 1)


class RegisterFile(Peripheral):
    """A peripheral whose registers are plain storage unless a subclass gives them behaviour: `RESET` maps each
    word offset to its reset value (offsets outside it are unmodelled); `WRITABLE` masks the bits software may
    set (default all)."""

    RESET: ClassVar[dict[int, int]] = {}
    WRITABLE: ClassVar[dict[int, int]] = {}

    def reset(self) -> None:
        self.regs = dict(self.RESET)

    def word(self, offset: int, access: str) -> int:
        word = offset & ~3
        if word not in self.regs:
            raise unknown_register(self, offset, access)
        return word

    def read(self, offset: int, size: int, now: int) -> int:
        word = self.word(offset, "read")
        return lane(self.load(word, now), offset, size)

    def write(self, offset: int, size: int, value: int, now: int) -> None:
        word = self.word(offset, "write")
        old = self.load(word, now)
        new = merge(old, offset, size, value)
        mask = self.WRITABLE.get(word, 0xFFFF_FFFF)
        self.store(word, (old & ~mask) | (new & mask), now)

    def load(self, word: int, now: int) -> int:
        """The register's value at `now` (subclasses compute status bits here)."""
        return self.regs[word]

    def store(self, word: int, value: int, now: int) -> None:
        """Software wrote `value` (masked by WRITABLE) to the register at `word` at `now`."""
        self.regs[word] = value
