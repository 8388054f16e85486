"""Firmware parameters (firmware_stub/target/hil_app_params.h, docs/firmware_api.md "Firmware parameters"): the
named parameters a firmware declares in its exported table `hil_app_params`, read from the firmware file itself
(the SIL library or the MCU ELF: the same 52-byte little-endian entries), so `hil run --param NAME=VALUE`,
sweeps and the pytest plugin accept them for a `sil:PATH` / `qemu:PATH` target."""

from __future__ import annotations

import functools
import math
import os
import re
import struct
from dataclasses import dataclass
from pathlib import Path

from pmsm_hil.protocol.ids import ParamId
from pmsm_hil.sim_target.elf import ElfError, elf_object, elf_symbols
from pmsm_hil.sim_target.firmware import FirmwareError

#: ConfigParam ids kept for firmware-declared parameters (hil_app_params.h HIL_APP_PARAM_ID_FIRST..LAST)
ID_FIRST, ID_LAST = 128, 254
#: one entry: name[24], unit[12], id u8, 3 reserved bytes, default, min, max (float32)
_ENTRY = struct.Struct("<24s12sB3xfff")
_NAME = re.compile(r"[a-z][a-z0-9_]*")
TABLE_SYMBOL = "hil_app_params"


class FirmwareParamError(FirmwareError):
    """A firmware's parameter table is malformed (the message names the firmware and the entry)."""


class FirmwareParamId(int):
    """The ConfigParam id of a firmware-declared parameter, carrying its `name` (like ParamId members do)."""

    name: str

    def __new__(cls, value: int, name: str) -> FirmwareParamId:
        obj = super().__new__(cls, value)
        obj.name = name
        return obj


@dataclass(frozen=True, slots=True)
class FirmwareParam:
    """One declared parameter: `--param name=VALUE` sends ConfigParam `id`; value in [min, max] (`unit`, SI)."""

    name: str
    unit: str
    id: int
    default: float
    min: float
    max: float

    @property
    def param_id(self) -> FirmwareParamId:
        """The id, named."""
        return FirmwareParamId(self.id, self.name)

    def check(self, value: float, option: str = "--param") -> None:
        """FirmwareParamError (one line, naming `option`) for a value outside [min, max]."""
        if not (math.isfinite(value) and self.min <= value <= self.max):
            unit = f" {self.unit}" if self.unit else ""
            raise FirmwareParamError(f"{option} {self.name}={value:g}: outside the firmware's range "
                                     f"[{self.min:g}, {self.max:g}]{unit}")


def _text(raw: bytes) -> str:
    return raw.split(b"\0", 1)[0].decode("ascii", "replace")


def firmware_params(path: str | Path) -> tuple[FirmwareParam, ...]:
    """The parameters the firmware file `path` declares (none for a firmware without a table, or a file that is
    not an ELF); a source folder (`sil:FOLDER`) is built for the host first, as the run does (cached).
    FirmwareParamError for a malformed table."""
    p = Path(path).expanduser()
    if p.is_dir():
        from pmsm_hil.sim_target.fw_build import build_firmware

        p = build_firmware("host", p).path
    try:
        st = p.stat()
    except OSError:
        return ()
    return _read(str(p.resolve()), st.st_mtime_ns, st.st_size)


@functools.lru_cache(maxsize=16)
def _read(path: str, _mtime_ns: int, _size: int) -> tuple[FirmwareParam, ...]:
    try:
        raw = elf_object(path, TABLE_SYMBOL)
    except (ElfError, OSError, ValueError, struct.error):
        return ()
    if not raw:
        return ()
    if len(raw) % _ENTRY.size:
        raise FirmwareParamError(f"{os.path.basename(path)}: {TABLE_SYMBOL} is {len(raw)} bytes, not a whole number "
                                 f"of {_ENTRY.size}-byte entries (hil_app_params.h)")
    out: list[FirmwareParam] = []
    protocol_names = {m.name.lower() for m in ParamId}
    for k in range(len(raw) // _ENTRY.size):
        name_b, unit_b, pid, default, lo, hi = _ENTRY.unpack_from(raw, k * _ENTRY.size)
        param = FirmwareParam(_text(name_b), _text(unit_b), pid, default, lo, hi)
        where = f"{os.path.basename(path)}: {TABLE_SYMBOL}[{k}] '{param.name}'"
        for field, value, size in (("name", name_b, 24), ("unit", unit_b, 12)):
            if b"\0" not in value:
                raise FirmwareParamError(f"{where}: {field} is not NUL-terminated within its {size} bytes "
                                         f"(at most {size - 1} characters)")
        for field, number in (("default", default), ("min", lo), ("max", hi)):
            if not math.isfinite(number):
                raise FirmwareParamError(f"{where}: {field} {number:g} is not a finite number")
        if not lo <= hi:
            raise FirmwareParamError(f"{where}: min {lo:g} above max {hi:g}")
        if not _NAME.fullmatch(param.name) or param.name in protocol_names:
            raise FirmwareParamError(f"{where}: a name is lower case [a-z0-9_] and not a protocol parameter's")
        if not (ID_FIRST <= pid <= ID_LAST):
            raise FirmwareParamError(f"{where}: id {pid} outside {ID_FIRST}..{ID_LAST}")
        if any(q.name == param.name or q.id == pid for q in out):
            raise FirmwareParamError(f"{where}: name or id {pid} declared twice")
        if not (lo <= default <= hi):
            raise FirmwareParamError(f"{where}: default {default:g} outside [{lo:g}, {hi:g}]")
        out.append(param)
    return tuple(out)


#: a symbol only the reference firmware has (firmware_stub/src/state.c, called by hil_app_reference.c)
REFERENCE_SYMBOL = "hil_fw_select_controller"


def default_controller(target: str, fallback: str) -> str:
    """`external` for `sil:PATH` / `qemu:PATH` naming a firmware other than the reference firmware (a user's
    firmware implements its own control law, selected as controller 255 `external`), else `fallback`."""
    kind, sep, path = target.partition(":")
    if not sep or kind not in ("sil", "qemu"):
        return fallback
    folder = Path(path.strip()).expanduser()
    if folder.is_dir():  # a source folder, built by the run: the reference firmware's own, or a user's
        from pmsm_hil.sim_target.fw_build import REFERENCE_SRC

        return fallback if folder.resolve() == REFERENCE_SRC.resolve() else "external"
    try:
        symbols = elf_symbols(path.strip())
    except (ElfError, OSError, ValueError, struct.error):
        return fallback  # missing or not an ELF: the target's own check names the problem
    return fallback if REFERENCE_SYMBOL in symbols else "external"
