"""Verdicts of strict C compiles, kept per content and shared by every pytest process of the user.

A compile that succeeded leaves an entry: the command (compiler, flags, source) with the compiler's `--version`
as its key, and the sha256 of every file the compiler read (its `-MD` dependency list: the source, the project's
headers, the system's). The same command is a hit when every one of those files still has its hash: the verdict a
fresh compile of the same bytes by the same compiler gives. A failure is never kept (its message is compiled
again)."""

from __future__ import annotations

import functools
import hashlib
import json
import os
import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

from pmsm_hil.sim_target.fw_build import cache_dir
from tests.cache_prune import remove_stale


@functools.cache
def _version(compiler: str) -> str:
    """`compiler`'s path and first `--version` line (once per process)."""
    exe = shutil.which(compiler) or compiler
    proc = subprocess.run([exe, "--version"], capture_output=True, text=True, check=False, timeout=60)
    return f"{os.path.realpath(exe)} {proc.stdout.splitlines()[:1]}"


def _digests(paths: Sequence[str]) -> dict[str, str | None]:
    out: dict[str, str | None] = {}
    for path in paths:
        try:
            out[path] = hashlib.sha256(Path(path).read_bytes()).hexdigest()
        except OSError:
            out[path] = None
    return out


def _deps(text: str) -> list[str]:
    """The files of a make rule written by `-MD` (`obj: dep dep \\` ...)."""
    body = text.replace("\\\n", " ").split(":", 1)[1]
    return sorted(set(body.split()))


def compile_ok(cmd: Sequence[str], obj: Path) -> subprocess.CompletedProcess[str] | None:
    """Compile with `cmd` (a compiler command writing `obj`, without -MD): None when a compile of the same command
    and the same bytes of every file it read succeeded before (nothing run); else the finished compile."""
    args = [a for i, a in enumerate(cmd) if a != "-o" and (i == 0 or cmd[i - 1] != "-o")]  # not the object's path
    key = hashlib.sha256("\0".join((_version(cmd[0]), *args[1:])).encode())
    entry = cache_dir() / "strict-c" / f"{key.hexdigest()[:32]}.json"
    try:
        files = json.loads(entry.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        files = None
    if isinstance(files, dict) and files and _digests(sorted(files)) == files:
        entry.touch()  # used: not stale
        return None
    dep = obj.with_suffix(".d")
    result = subprocess.run([*cmd, "-MD", "-MF", str(dep)], capture_output=True, text=True, check=False)
    if result.returncode == 0:
        files = _digests(_deps(dep.read_text(encoding="utf-8")))
        if all(files.values()):  # every file read is still there: the verdict is theirs
            entry.parent.mkdir(parents=True, exist_ok=True)
            part = entry.with_name(f"{entry.stem}.{os.getpid()}.partial")
            part.write_text(json.dumps(files), encoding="utf-8")
            part.replace(entry)
            remove_stale(entry.parent, "*.json")  # a test's own sources below its tmp path make one a session
    return result

