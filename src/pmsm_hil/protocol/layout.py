"""Frame layouts compiled from `hil.dbc`: one `struct` format per message.

Byte-aligned 8/16/32/64-bit signals become struct fields; runs of packed signals (6-bit states,
20-bit durations) become byte-aligned groups unpacked as integers and split with precomputed shifts
and masks. The pack/unpack functions are generated as Python source (no per-call interpretation of
the layout), which keeps a frame at ~1 µs. The layouts of the bundled `hil.dbc` are that source
written out (`compiled_layouts.py`, by `python -m pmsm_hil.protocol.gen_c`, checked by its `--check`):
while `hil.dbc`'s sha256 is the one it was generated from, `load_layouts()` imports it instead of
parsing the DBC with cantools (cantools' import and the parsing cost ~0.2 CPU-s of every process's start-up);
an edited `hil.dbc`, or another file, is parsed and compiled as before.
"""

from __future__ import annotations

import hashlib
import re
import struct
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache
from pathlib import Path
from typing import Any

from pmsm_hil.protocol.errors import DatabaseError

DBC_PATH = Path(__file__).with_name("hil.dbc")

_ALIGNED_INT = {8: "B", 16: "H", 32: "I", 64: "Q"}
_GROUP_CHUNKS = ((8, "Q"), (4, "I"), (2, "H"), (1, "B"))


@dataclass(frozen=True, slots=True)
class SignalInfo:
    """One DBC signal: little-endian bit position, width, sign, scale (phys = raw·scale + offset)."""

    name: str
    start: int
    length: int
    signed: bool
    is_float: bool
    scale: float
    offset: float

    @property
    def raw_min(self) -> int:
        """Smallest raw integer value."""
        return -(1 << (self.length - 1)) if self.signed else 0

    @property
    def raw_max(self) -> int:
        """Largest raw integer value."""
        return (1 << (self.length - 1)) - 1 if self.signed else (1 << self.length) - 1

    @property
    def aligned(self) -> bool:
        """True if the signal is a whole byte-aligned struct field."""
        return self.start % 8 == 0 and (self.length in _ALIGNED_INT or self.is_float)


@dataclass(frozen=True, slots=True)
class FrameLayout:
    """Compiled layout of one DBC message; `pack(*raw)` and `unpack(data)` use signal order."""

    name: str
    frame_id: int
    length: int
    is_fd: bool
    signals: tuple[SignalInfo, ...]
    struct_format: str
    pack: Callable[..., bytes]
    unpack: Callable[[bytes], tuple[Any, ...]]
    #: the DBC's sending nodes of the message ("Host", "Target")
    senders: tuple[str, ...] = ()

    def signal(self, name: str) -> SignalInfo:
        """The signal called `name`; raises DatabaseError if absent."""
        for sig in self.signals:
            if sig.name == name:
                return sig
        raise DatabaseError(f"message {self.name} has no signal {name!r}")

    def index(self, name: str) -> int:
        """Position of signal `name` in pack/unpack order."""
        return self.signals.index(self.signal(name))


def _signal_info(sig: Any, msg_name: str) -> SignalInfo:
    if sig.byte_order != "little_endian":
        raise DatabaseError(f"{msg_name}.{sig.name}: only little-endian (Intel) signals are supported")
    if sig.is_float and sig.length not in (32, 64):
        raise DatabaseError(f"{msg_name}.{sig.name}: float signals must be 32 or 64 bits")
    return SignalInfo(
        sig.name,
        int(sig.start),
        int(sig.length),
        bool(sig.is_signed),
        bool(sig.is_float),
        float(sig.scale),
        float(sig.offset),
    )


def _chunks(nbytes: int) -> list[tuple[int, str]]:
    """Split a group of `nbytes` into (byte offset, struct code) chunks."""
    out: list[tuple[int, str]] = []
    off = 0
    while off < nbytes:
        for size, code in _GROUP_CHUNKS:
            if size <= nbytes - off:
                out.append((off, code))
                off += size
                break
    return out


def _compile(
    name: str, length: int, signals: tuple[SignalInfo, ...]
) -> tuple[str, Callable[..., bytes], Callable[[bytes], tuple[Any, ...]]]:
    """Generate pack/unpack source for one message and exec it."""
    fmt, src = layout_source(name, length, signals)
    namespace: dict[str, Any] = {"_st": struct.Struct(fmt), "_sx": sign_extend}
    exec("\n".join(src), namespace)  # generated from the DBC above; no external input
    return fmt, namespace["pack"], namespace["unpack"]


def layout_source(
    name: str, length: int, signals: tuple[SignalInfo, ...], *, st: str = "_st", pack: str = "pack",
    unpack: str = "unpack", typed: bool = False,
) -> tuple[str, list[str]]:
    """The struct format and the source lines of `def pack(s0, s1, ...)` and `def unpack(data)` of one message:
    `st` names its `struct.Struct`, `_sx` is `sign_extend`; `typed` annotates the functions (a module's source)."""
    order = sorted(range(len(signals)), key=lambda i: signals[i].start)
    fmt = "<"
    pack_items: list[str] = []  # expressions passed to struct.pack
    unpack_names: list[str] = []  # names bound by struct.unpack
    unpack_lines: list[str] = []
    result: dict[int, str] = {}
    pos = 0  # byte position
    k = 0
    while k < len(order):
        i = order[k]
        sig = signals[i]
        byte0 = sig.start // 8
        if byte0 < pos:
            raise DatabaseError(f"{name}.{sig.name}: overlapping signals")
        fmt += "x" * (byte0 - pos)
        if sig.aligned:
            code = "f" if sig.is_float and sig.length == 32 else "d" if sig.is_float else _ALIGNED_INT[sig.length]
            if sig.signed and not sig.is_float:
                code = code.lower()
            fmt += code
            pack_items.append(f"s{i}")
            unpack_names.append(f"s{i}")
            result[i] = f"s{i}"
            pos = byte0 + sig.length // 8
            k += 1
            continue
        members = [i]
        end_bit = sig.start + sig.length
        k += 1
        while k < len(order) and not signals[order[k]].aligned and signals[order[k]].start < (end_bit + 7) // 8 * 8:
            members.append(order[k])
            end_bit = max(end_bit, signals[order[k]].start + signals[order[k]].length)
            k += 1
        nbytes = (end_bit + 7) // 8 - byte0
        g = f"g{byte0}"
        base = byte0 * 8
        terms = [f"((s{m} & {(1 << signals[m].length) - 1}) << {signals[m].start - base})" for m in members]
        parts = _chunks(nbytes)
        for off, code in parts:
            fmt += code
            width = struct.calcsize("<" + code) * 8
            pack_items.append(f"(({' | '.join(terms)}) >> {off * 8}) & {(1 << width) - 1}")
            unpack_names.append(f"{g}_{off}")
        unpack_lines.append(f"    {g} = " + " | ".join(f"({g}_{off} << {off * 8})" for off, _ in parts))
        for m in members:
            s = signals[m]
            expr = f"(({g} >> {s.start - base}) & {(1 << s.length) - 1})"
            if s.signed:
                expr = f"_sx({expr}, {s.length})"
            result[m] = expr
        pos = byte0 + nbytes
    if pos > length:
        raise DatabaseError(f"{name}: signals exceed the {length}-byte frame")
    fmt += "x" * (length - pos)
    args = ", ".join(f"s{i}: Any" if typed else f"s{i}" for i in range(len(signals)))
    src = [f"def {pack}({args}){' -> bytes' if typed else ''}:", f"    return {st}.pack({', '.join(pack_items)})",
           f"def {unpack}(data{': bytes) -> tuple[Any, ...]' if typed else ')'}:"]
    src.append(f"    ({', '.join(unpack_names)},) = {st}.unpack(data)")
    src.extend(unpack_lines)
    src.append(f"    return ({', '.join(result[i] for i in range(len(signals)))},)")
    return fmt, src


def sign_extend(value: int, bits: int) -> int:
    """`value`, an unsigned `bits`-bit integer, as two's complement."""
    return value - (1 << bits) if value >> (bits - 1) else value


def dbc_sha256(path: Path = DBC_PATH) -> str:
    """The sha256 (hex) of the file `path`'s bytes."""
    return hashlib.sha256(path.read_bytes()).hexdigest()


@cache
def load_layouts(path: Path = DBC_PATH) -> dict[str, FrameLayout]:
    """Every message of the DBC `path` compiled, keyed by DBC message name: for the bundled `hil.dbc` unchanged
    since `compiled_layouts.py` was generated, that module's layouts; else the DBC parsed (once) and compiled. A
    DBC that cantools cannot parse or this codec cannot compile is a DatabaseError of one line naming the file, the
    line and the message.signal where they can be found."""
    if path == DBC_PATH:
        from pmsm_hil.protocol import compiled_layouts

        try:
            current = dbc_sha256(path)
        except OSError:
            current = ""  # parse_layouts names the error
        if current == compiled_layouts.DBC_SHA256:
            return dict(compiled_layouts.LAYOUTS)
    return parse_layouts(path)


def parse_layouts(path: Path = DBC_PATH) -> dict[str, FrameLayout]:
    """The DBC `path` parsed with cantools and every message compiled (what `load_layouts` does but for an
    unchanged `hil.dbc`, and what `compiled_layouts.py` is generated from)."""
    import cantools
    from cantools.database.can import Database as CanDatabase
    from cantools.database.errors import Error as CantoolsError
    from cantools.database.errors import UnsupportedDatabaseFormatError

    try:
        db = cantools.database.load_file(str(path))
    except OSError as exc:
        raise DatabaseError(f"cannot load {path}: {exc.strerror or exc}") from None
    except (UnsupportedDatabaseFormatError, CantoolsError, ValueError, KeyError, IndexError) as exc:
        raise DatabaseError(locate_in_dbc(path, _one_line(str(exc)))) from None
    if not isinstance(db, CanDatabase):
        raise DatabaseError(f"{path} is not a CAN database")
    layouts: dict[str, FrameLayout] = {}
    for msg in db.messages:
        try:
            if msg.is_extended_frame:
                raise DatabaseError(f"{msg.name}: only 11-bit identifiers are used")
            sigs = tuple(_signal_info(s, msg.name) for s in msg.signals)
            fmt, pack, unpack = _compile(msg.name, int(msg.length), sigs)
        except DatabaseError as exc:
            raise DatabaseError(locate_in_dbc(path, str(exc))) from None
        layouts[msg.name] = FrameLayout(
            msg.name, int(msg.frame_id), int(msg.length), bool(msg.is_fd), sigs, fmt, pack, unpack,
            tuple(str(node) for node in msg.senders or ()),
        )
    return layouts


def _one_line(text: str) -> str:
    """cantools' message on one line (its syntax errors quote the line; some list entries on new lines)."""
    text = text.strip()
    text = text.removeprefix("DBC:").strip().strip('"')
    return " ".join(part.strip() for part in text.splitlines() if part.strip())


_AT_LINE = re.compile(r"at line (\d+)")
_MSG_SIG = re.compile(r"^(\w+)\.(\w+):")
_MSG = re.compile(r"^(\w+):")
_CANTOOLS_NAMES = (re.compile(r"signal (\w+) does not fit in message (\w+)"),
                   re.compile(r"signals (\w+) and \w+ are overlapping in message (\w+)"))
_VAL_ENTRY = re.compile(r"VAL_ (\d+) (\w+)")


def locate_in_dbc(path: Path, reason: str) -> str:
    """`reason` prefixed with `path` and the DBC line it concerns ("hil.dbc line 34: FaultHost.node: ...")."""
    if at := _AT_LINE.search(reason):
        field = _field_at(path, int(at.group(1)))
        return f"{path} line {at.group(1)}{f' ({field})' if field else ''}: {reason}"
    message = signal = None
    frame_id: int | None = None
    if m := _MSG_SIG.match(reason):
        message, signal = m.group(1), m.group(2)
    elif m := _MSG.match(reason):
        message = m.group(1)
    elif m := _CANTOOLS_NAMES[0].search(reason) or _CANTOOLS_NAMES[1].search(reason):
        signal, message = m.group(1), m.group(2)
        reason = f"{message}.{signal}: {reason}"
    elif m := _VAL_ENTRY.search(reason):
        frame_id, signal = int(m.group(1)), m.group(2)
    line = _dbc_line(path, message, signal, frame_id)
    if line is None and m is not None and m.re is _VAL_ENTRY:
        line = _first_line(path, lambda words: words[:3] == ["VAL_", str(frame_id), signal])
    return f"{path} line {line}: {reason}" if line is not None else f"{path}: {reason}"


def _lines(path: Path) -> list[str]:
    try:
        return path.read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return []


def _first_line(path: Path, test: Callable[[list[str]], bool]) -> int | None:
    """1-based number of the first line of `path` whose words pass `test`."""
    return next((n for n, line in enumerate(_lines(path), start=1) if test(line.split())), None)


def _field_at(path: Path, number: int) -> str:
    """"Message.signal" (or "Message") of DBC line `number`, '' if it is neither a BO_ nor an SG_ line."""
    message = ""
    for line in _lines(path)[:number]:
        words = line.split()
        if words[:1] == ["BO_"] and len(words) >= 3:
            message = words[2].rstrip(":")
    words = (_lines(path)[number - 1:number] or [""])[0].split()
    if words[:1] == ["SG_"] and len(words) >= 2:
        return f"{message}.{words[1]}" if message else words[1]
    if words[:1] == ["BO_"]:
        return message
    return ""


def _dbc_line(path: Path, message: str | None, signal: str | None, frame_id: int | None = None) -> int | None:
    """1-based line of `BO_ ... message` (by name or id), or of its signal `signal`, in the DBC `path`."""
    if message is None and frame_id is None:
        return None
    inside = False
    for number, line in enumerate(_lines(path), start=1):
        words = line.split()
        if words[:1] == ["BO_"] and len(words) >= 3:
            inside = words[2].rstrip(":") == message or words[1] == str(frame_id)
            if inside and signal is None:
                return number
        elif inside and signal is not None and words[:1] == ["SG_"] and len(words) >= 2 and words[1] == signal:
            return number
    return None


def expect_layout(name: str, signals: tuple[str, ...]) -> FrameLayout:
    """The compiled layout of DBC message `name`; DatabaseError unless `hil.dbc` has it with exactly
    the signals `signals`, in that order (what the hand-written codec relies on)."""
    layout = load_layouts().get(name)
    if layout is None:
        raise DatabaseError(f"{DBC_PATH}: lacks message {name}")
    found = tuple(s.name for s in layout.signals)
    if found != signals:
        raise DatabaseError(locate_in_dbc(DBC_PATH, f"{name}: signals {found}, codec expects {signals}"))
    return layout


@cache
def load_database(path: Path = DBC_PATH) -> Any:
    """The cantools database (for tools and cross-checks; not used on the hot path)."""
    import cantools

    return cantools.database.load_file(str(path))
