"""The firmware build cache keyed by content: a built firmware is found again for the same inputs wherever they lie
(a second clone, a copy of a source folder) and never for changed ones.

The key is the sha256 of every file of the source folder and of the SDK folder (firmware_stub/: the target core, the
board files, the CMake functions and flags), the board, the `--define`s, the versions of cmake and of the board's
compilers and the compiler variables of the environment (CC, CFLAGS, ...). Files the compiler read outside those
folders and the system's (a header folder given by a define) are listed in the entry with their sha256 and
checked when it is found. An entry is a folder `<src name>-<board>-<key>` below `cache_dir()/fw-cache` holding the
artefact and `entry.json` (its warnings, section sizes, outside inputs); it is made in a temporary folder and
renamed into place, so a reader sees a whole entry or none; `lock()` lets one process build a key while the others
wait for it."""

from __future__ import annotations

import contextlib
import fcntl
import functools
import hashlib
import json
import os
import shutil
import subprocess
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

#: folders below a source folder that are not sources (a user's own build folder, VCS data, caches)
SKIPPED_DIRS = ("build", ".git", ".hg", ".svn", "__pycache__", ".cache", ".vscode", ".idea")
#: environment variables CMake takes compilers and flags from
COMPILER_ENV = ("CC", "CXX", "CFLAGS", "CXXFLAGS", "CPPFLAGS", "LDFLAGS", "ASMFLAGS")
#: the compilers whose versions go into the key, per board kind
HOST_TOOLS = ("cmake", "cc", "c++")
MCU_TOOLS = ("cmake", "arm-none-eabi-gcc", "arm-none-eabi-g++")
#: entries not used for this long are removed when a new one is stored [s]
STALE_S = 14 * 24 * 3600.0
#: placeholders of the source and SDK folders in stored warnings (an entry may be found from another folder)
_SRC, _SDK = "\x00SRC\x00", "\x00SDK\x00"
#: folders whose files the key covers through the tool versions
_SYSTEM = ("/usr/", "/lib/", "/opt/", "/etc/")


@dataclass(frozen=True, slots=True)
class Entry:
    """A cached firmware: the artefact, its warnings (paths of this lookup's folders), section sizes."""

    artefact: Path
    warnings: tuple[str, ...]
    sizes: tuple[int, int, int] | None


def _files(folder: Path) -> Iterator[Path]:
    """The files below `folder`, sorted, without SKIPPED_DIRS (and hidden folders)."""
    for root, dirs, files in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if d not in SKIPPED_DIRS and not d.startswith(".")
                         and not d.startswith("build-") and not d.startswith("cmake-build"))
        for name in sorted(files):
            yield Path(root) / name


def tree_digest(folder: Path) -> str:
    """sha256 of the files below `folder`: their paths relative to it and their bytes."""
    h = hashlib.sha256()
    for path in _files(folder):
        with contextlib.suppress(OSError):
            data = path.read_bytes()
            h.update(str(path.relative_to(folder)).encode() + b"\0" + len(data).to_bytes(8, "little") + data)
    return h.hexdigest()


@functools.cache
def _tool_version(tool: str) -> str:
    """The first lines of `tool --version` (with its path), or "missing"; once per process."""
    found = shutil.which(tool)
    if found is None:
        return f"{tool}: missing"
    try:
        proc = subprocess.run([found, "--version"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.SubprocessError):
        return f"{tool}: {found} unusable"
    return f"{tool}: {os.path.realpath(found)} {' '.join(proc.stdout.splitlines()[:1])}"


#: what an entry may hold and how a hit is used, in the key: a tool whose rules differ (2: artefacts whose parameter
#: table is refused are cached too, the table checked on every hit) never takes another's entries
ENTRY_RULES = 2


def content_key(src: Path, sdk: Path, board: str, defines: tuple[str, ...], *, mcu: bool) -> str:
    """The entry key (32 hex digits) of building `src` with the SDK `sdk` for `board` with `defines`."""
    h = hashlib.sha256()
    for part in (f"rules {ENTRY_RULES}", tree_digest(src), tree_digest(sdk), board, *defines, "\x01",
                 *(_tool_version(t) for t in (MCU_TOOLS if mcu else HOST_TOOLS)),
                 *(f"{k}={os.environ.get(k, '')}" for k in COMPILER_ENV)):
        h.update(part.encode() + b"\0")
    return h.hexdigest()[:32]


def root() -> Path:
    """The folder of the entries."""
    from pmsm_hil.sim_target.fw_build import cache_dir

    return cache_dir() / "fw-cache"


def entry_dir(src: Path, board: str, key: str) -> Path:
    """The entry folder of a key (the source folder's name and the board in its name, for people)."""
    return root() / f"{src.name}-{board}-{key}"


@contextlib.contextmanager
def lock(entry: Path) -> Iterator[None]:
    """Exclusive lock of an entry's key across processes (a file beside it)."""
    entry.parent.mkdir(parents=True, exist_ok=True)
    with open(entry.with_name(entry.name + ".lock"), "a+b") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _sha256(path: Path) -> str | None:
    try:
        return hashlib.sha256(path.read_bytes()).hexdigest()
    except OSError:
        return None


def find(entry: Path, artefact_name: str, src: Path, sdk: Path) -> Entry | None:
    """The entry when it is whole and every outside input it lists is unchanged, else None."""
    meta_path, artefact = entry / "entry.json", entry / artefact_name
    try:
        meta = json.loads(meta_path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not artefact.is_file():
        return None
    for path, digest in dict(meta.get("outside_inputs") or {}).items():
        if _sha256(Path(path)) != digest:
            return None
    with contextlib.suppress(OSError):
        os.utime(entry)  # used now: not pruned
    warnings = tuple(str(w).replace(_SRC, str(src)).replace(_SDK, str(sdk)) for w in meta.get("warnings") or ())
    sizes = meta.get("sizes")
    return Entry(artefact, warnings, None if sizes is None else (int(sizes[0]), int(sizes[1]), int(sizes[2])))


def outside_inputs(build: Path, src: Path, sdk: Path) -> dict[str, str]:
    """The files the compiler read (its dependency files in the build folder) that lie outside `src`, `sdk`, the
    build folder and the system's folders: path -> sha256."""
    inside = [str(p.resolve()) + os.sep for p in (src, sdk, build)]
    found: dict[str, str] = {}
    for dep in build.rglob("*.d"):
        with contextlib.suppress(OSError):
            text = dep.read_text(encoding="utf-8", errors="replace").replace("\\\n", " ")
            for token in text.split():
                if token.endswith(":") or not token.startswith("/"):
                    continue
                path = os.path.realpath(token)
                if path in found or any(path.startswith(p) for p in (*inside, *_SYSTEM)):
                    continue
                digest = _sha256(Path(path))
                if digest is not None:
                    found[path] = digest
    return found


def store(entry: Path, artefact: Path, warnings: tuple[str, ...], sizes: tuple[int, int, int] | None,
          outside: dict[str, str], src: Path, sdk: Path) -> Path:
    """Store a built artefact as `entry` (replacing an entry whose outside inputs changed); its path there."""
    tmp = entry.with_name(f"{entry.name}.{os.getpid()}.tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    tmp.mkdir(parents=True)
    shutil.copy2(artefact, tmp / artefact.name)
    meta = {"warnings": [w.replace(str(src), _SRC).replace(str(sdk), _SDK) for w in warnings],
            "sizes": None if sizes is None else list(sizes), "outside_inputs": outside}
    (tmp / "entry.json").write_text(json.dumps(meta, indent=1), encoding="utf-8")
    if entry.exists():  # stale (an outside input changed): moved away, then removed
        old = entry.with_name(f"{entry.name}.{os.getpid()}.old")
        os.replace(entry, old)
        shutil.rmtree(old, ignore_errors=True)
    os.replace(tmp, entry)
    _prune(entry)
    return entry / artefact.name


def _prune(keep: Path) -> None:
    """Remove entries not used for STALE_S."""
    now = time.time()
    with contextlib.suppress(OSError):
        for entry in keep.parent.iterdir():
            if entry.is_dir() and entry != keep and now - entry.stat().st_mtime > STALE_S:
                shutil.rmtree(entry, ignore_errors=True)
                entry.with_name(entry.name + ".lock").unlink(missing_ok=True)
