"""Symbols of an ELF file (32- or 64-bit, little-endian): enough to find a firmware's markers and
configuration block without binutils."""

from __future__ import annotations

import struct
from pathlib import Path

from pmsm_hil.errors import HilError


class ElfError(HilError, ValueError):
    """Not an ELF file this reader understands, or no symbol table."""


def elf_symbols(path: str | Path) -> dict[str, int]:
    """name -> value of every named symbol in .symtab (Thumb function addresses keep bit 0)."""
    data = Path(path).read_bytes()
    if data[:4] != b"\x7fELF":
        raise ElfError(f"{path}: not an ELF file")
    is64 = data[4] == 2
    if data[5] != 1:
        raise ElfError(f"{path}: big-endian ELF is not supported")
    if is64:
        shoff, = struct.unpack_from("<Q", data, 0x28)
        shentsize, shnum = struct.unpack_from("<HH", data, 0x3A)
    else:
        shoff, = struct.unpack_from("<I", data, 0x20)
        shentsize, shnum = struct.unpack_from("<HH", data, 0x2E)
    sections = []
    for i in range(shnum):
        off = shoff + i * shentsize
        if is64:
            _, sh_type, _, _, sh_offset, sh_size, sh_link, _, _, sh_entsize = struct.unpack_from(
                "<IIQQQQIIQQ", data, off)
        else:
            _, sh_type, _, _, sh_offset, sh_size, sh_link, _, _, sh_entsize = struct.unpack_from(
                "<IIIIIIIIII", data, off)
        sections.append((sh_type, sh_offset, sh_size, sh_link, sh_entsize))
    symtab = next((s for s in sections if s[0] == 2), None)  # SHT_SYMTAB
    if symtab is None:
        raise ElfError(f"{path}: no symbol table (stripped?)")
    _, off, size, link, entsize = symtab
    str_off = sections[link][1]
    out: dict[str, int] = {}
    for pos in range(off, off + size, entsize):
        if is64:
            name, _, _, _, value, _ = struct.unpack_from("<IBBHQQ", data, pos)
        else:
            name, value, _, _, _, _ = struct.unpack_from("<IIIBBH", data, pos)
        if name:
            end = data.index(b"\x00", str_off + name)
            out[data[str_off + name:end].decode("ascii", "replace")] = value
    return out
