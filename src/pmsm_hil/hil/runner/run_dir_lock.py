"""`run_dir_lock`: one run at a time writes into a run directory (an exclusive `flock` on a file in it).

Two runs into the same `--out` would interleave their MCAP writes and leave the metrics.json of one beside
the log of the other. The lock is held from before the directory is prepared (an earlier run removed with
`--overwrite`) until metrics.json is written; the kernel releases it when the process ends, however it
ends, so a killed run never leaves a stale lock (only its file, `.hil-run.lock`, holding its pid). A run that
ends removes the file before it lets the lock go; a run that locked a file removed meanwhile tries again.
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import threading
from collections.abc import Iterator
from pathlib import Path

from pmsm_hil.hil.atomic_write import ensure_dir
from pmsm_hil.hil.errors import InputFileError

LOCK_NAME = ".hil-run.lock"

_held: dict[Path, int] = {}  # directories this process holds -> nesting depth (the CLI and the runner both lock)
_held_guard = threading.Lock()


class RunDirLockedError(InputFileError):
    """Another run (another process) is writing into the run directory."""


@contextlib.contextmanager
def run_dir_lock(path: Path, *, option: str = "--out") -> Iterator[None]:
    """Hold the exclusive lock of run directory `path` (created if missing) inside; RunDirLockedError naming
    `option` if another process holds it, InputFileError if `path` is a file or cannot be created. Nested
    uses in one process share the lock."""
    path = ensure_dir(path, option=option)
    key = path.resolve()
    with _held_guard:
        nested = key in _held
        if nested:
            _held[key] += 1
    if nested:
        try:
            yield
        finally:
            with _held_guard:
                _held[key] -= 1
        return
    fd = _acquire(path, option)
    with _held_guard:
        _held[key] = 1
    try:
        yield
    finally:
        with _held_guard:
            del _held[key]
        with contextlib.suppress(OSError):
            (path / LOCK_NAME).unlink()  # while still held: whoever opened it finds it gone and tries again
        os.close(fd)  # releases the lock


def _acquire(path: Path, option: str) -> int:
    lock = path / LOCK_NAME
    while True:
        try:
            fd = os.open(lock, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        except OSError as exc:
            raise InputFileError(f"{option} {path}: cannot create the lock file {LOCK_NAME} ({exc.strerror})") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = _read_pid(fd)
            os.close(fd)
            who = f" (pid {holder})" if holder else ""
            raise RunDirLockedError(f"{option} {path}: another run{who} is writing into this directory; wait for "
                                    "it to end or choose another directory") from None
        except OSError as exc:
            os.close(fd)
            raise InputFileError(f"{option} {path}: cannot lock {LOCK_NAME} ({exc.strerror})") from None
        if _same_inode(fd, lock):
            break
        os.close(fd)  # the file was removed by the run that held it: lock the one there now
    with contextlib.suppress(OSError):
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
    return fd


def _same_inode(fd: int, path: Path) -> bool:
    try:
        st = os.stat(path)
    except OSError:
        return False
    own = os.fstat(fd)
    return (st.st_dev, st.st_ino) == (own.st_dev, own.st_ino)


def _read_pid(fd: int) -> str:
    try:
        text = os.pread(fd, 32, 0).decode(errors="replace").strip()
    except OSError:
        return ""
    return text if text.isdigit() else ""
