"""Symbols of an ELF file (32- or 64-bit, little-endian): enough to find a firmware's markers and
configuration block, read its parameter table (`elf_object`) and name the function at a fault's PC
(`elf_function_at`) without binutils."""

from __future__ import annotations

import struct
from pathlib import Path

from pmsm_hil.errors import HilError


class ElfError(HilError, ValueError):
    """Not an ELF file this reader understands, or no symbol table."""


def elf_symbols(path: str | Path) -> dict[str, int]:
    """name -> value of every named symbol in .symtab (Thumb function addresses keep bit 0)."""
    return {name: sym[0] for name, sym in _symbols(Path(path).read_bytes(), path)[0].items()}


def elf_object(path: str | Path, name: str) -> bytes | None:
    """The initial bytes of the data object `name` (a symbol with a size, in a section with file contents:
    .rodata, .data, .text), None when the ELF has no such symbol."""
    data = Path(path).read_bytes()
    symbols, sections = _symbols(data, path)
    sym = symbols.get(name)
    if sym is None:
        return None
    value, size, shndx, _ = sym
    if not (0 < shndx < len(sections)):
        return None
    sh_type, sh_offset, sh_size, _, _, sh_addr = sections[shndx]
    start = value - sh_addr
    if sh_type == 8 or start < 0 or start + size > sh_size:  # SHT_NOBITS (.bss): no initial bytes in the file
        return None
    return data[sh_offset + start:sh_offset + start + size]


def elf_function_at(path: str | Path, address: int) -> str | None:
    """`name+0xOFF` of the function whose code holds `address` (Thumb bit ignored), None when none does."""
    symbols, _ = _symbols(Path(path).read_bytes(), path)
    address &= ~1
    for name, (value, size, _, kind) in symbols.items():
        start = value & ~1
        if kind == 2 and start <= address < start + max(size, 1):  # STT_FUNC
            return f"{name}+{address - start:#x}"
    return None


def _symbols(data: bytes, path: str | Path) -> tuple[dict[str, tuple[int, int, int, int]], list[tuple[int, ...]]]:
    """(name -> (value, size, section index, type) of every named symbol in .symtab, the section headers as (type,
    offset, size, link, entsize, addr))."""
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
    sections: list[tuple[int, ...]] = []
    for i in range(shnum):
        off = shoff + i * shentsize
        if is64:
            _, sh_type, _, sh_addr, sh_offset, sh_size, sh_link, _, _, sh_entsize = struct.unpack_from(
                "<IIQQQQIIQQ", data, off)
        else:
            _, sh_type, _, sh_addr, sh_offset, sh_size, sh_link, _, _, sh_entsize = struct.unpack_from(
                "<IIIIIIIIII", data, off)
        sections.append((sh_type, sh_offset, sh_size, sh_link, sh_entsize, sh_addr))
    symtab = next((s for s in sections if s[0] == 2), None)  # SHT_SYMTAB
    if symtab is None:
        raise ElfError(f"{path}: no symbol table (stripped?)")
    _, off, size, link, entsize, _ = symtab
    str_off = sections[link][1]
    out: dict[str, tuple[int, int, int, int]] = {}
    for pos in range(off, off + size, entsize):
        if is64:
            name, info, _, shndx, value, sym_size = struct.unpack_from("<IBBHQQ", data, pos)
        else:
            name, value, sym_size, info, _, shndx = struct.unpack_from("<IIIBBH", data, pos)
        if name:
            end = data.index(b"\x00", str_off + name)
            out[data[str_off + name:end].decode("ascii", "replace")] = (value, sym_size, shndx, info & 0xF)
    return out, sections


def elf_load_segments(path: str | Path) -> tuple[int, list[tuple[int, bytes]]]:
    """(entry point, [(load address, bytes)] of every PT_LOAD segment with file contents) of a 32-bit
    little-endian ELF: what a programmer writes into the part (the load address is the physical one, p_paddr,
    so .data's initial values land in flash where the start-up code copies them from)."""
    data = Path(path).read_bytes()
    if data[:4] != b"\x7fELF" or data[4] != 1 or data[5] != 1:
        raise ElfError(f"{path}: not a 32-bit little-endian ELF file")
    entry, phoff = struct.unpack_from("<II", data, 0x18)
    phentsize, phnum = struct.unpack_from("<HH", data, 0x2A)
    segments = []
    for i in range(phnum):
        p_type, p_offset, _, p_paddr, p_filesz, _, _, _ = struct.unpack_from("<IIIIIIII", data, phoff + i * phentsize)
        if p_type == 1 and p_filesz:
            if p_offset + p_filesz > len(data):
                raise ElfError(f"{path}: segment {i} extends past the end of the file")
            segments.append((p_paddr, data[p_offset:p_offset + p_filesz]))
    if not segments:
        raise ElfError(f"{path}: no loadable segment")
    return entry, segments
