"""CMake build trees of firmware_stub's unit tests, built once per content of their inputs and shared by every
pytest process of the user (xdist workers, concurrent sessions, later sessions).

The key is a hash of every file under firmware_stub/, the CMake arguments and the versions of cmake and the C
compiler: a tree is reused only for byte-identical inputs, so its build result (strict flags, -Werror, UBSan) is
the one a fresh build would give. A miss builds under a file lock (a second process waits for the first build and
reuses it); a tree counts as built only once its build succeeded (a marker file), so an interrupted build is
redone. ctest runs under the same lock: ctest writes its logs into the tree."""

from __future__ import annotations

import contextlib
import fcntl
import hashlib
import shutil
import subprocess
import time
from collections.abc import Iterator, Sequence
from pathlib import Path

from pmsm_hil.sim_target.fw_build import cache_dir

#: trees not used for this long are removed when a new tree is built [s]
STALE_S = 3 * 24 * 3600.0


class CMakeBuildError(AssertionError):
    """The configure or build step failed: the command's output."""


def _tool_versions() -> str:
    out = []
    for cmd in (["cmake", "--version"], ["cc", "--version"]):
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
        out.append(proc.stdout.splitlines()[0] if proc.stdout else "")
    return "\n".join(out)


def inputs_key(src: Path, cmake_args: Sequence[str]) -> str:
    """sha256 (16 hex digits) of every file below `src` (path and bytes), the arguments and the tool versions."""
    h = hashlib.sha256()
    for path in sorted(p for p in src.rglob("*") if p.is_file()):
        h.update(str(path.relative_to(src)).encode() + b"\0" + path.read_bytes() + b"\0")
    h.update("\0".join(cmake_args).encode() + b"\0" + _tool_versions().encode())
    return h.hexdigest()[:16]


@contextlib.contextmanager
def locked(tree: Path) -> Iterator[None]:
    """Exclusive lock of a tree (a file beside it), across processes."""
    with open(tree.with_suffix(".lock"), "a+b") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(fh, fcntl.LOCK_UN)


def _prune(root: Path, keep: Path) -> None:
    now = time.time()
    for tree in root.iterdir():
        if tree.is_dir() and tree != keep and now - tree.stat().st_mtime > STALE_S:
            shutil.rmtree(tree, ignore_errors=True)
            tree.with_suffix(".lock").unlink(missing_ok=True)


def cmake_tree(name: str, src: Path, cmake_args: Sequence[str] = (), *, jobs: int = 2) -> Path:
    """The built tree of `src` configured with `cmake_args` (cached; see the module's docstring). Raises
    CMakeBuildError with the output of the step that failed."""
    root = cache_dir() / "cmake-trees"
    root.mkdir(parents=True, exist_ok=True)
    tree = root / f"{name}-{inputs_key(src, cmake_args)}"
    with locked(tree):
        if not (tree / ".built").is_file():
            shutil.rmtree(tree, ignore_errors=True)
            # configure in the final path: CMake writes absolute paths into the tree
            cfg = subprocess.run(["cmake", "-S", str(src), "-B", str(tree), *cmake_args], capture_output=True,
                                 text=True, timeout=300)
            if cfg.returncode != 0:
                raise CMakeBuildError(cfg.stdout + cfg.stderr)
            out = subprocess.run(["cmake", "--build", str(tree), "-j", str(jobs)], capture_output=True, text=True,
                                 timeout=900)
            if out.returncode != 0:
                shutil.rmtree(tree, ignore_errors=True)
                raise CMakeBuildError(out.stdout + out.stderr)
            (tree / ".built").write_text(out.stdout, encoding="utf-8")
            _prune(root, tree)
        tree.touch()
    return tree


def ctest(tree: Path, *args: str, timeout_s: float = 600.0) -> subprocess.CompletedProcess[str]:
    """`ctest ARGS` in the tree, under its lock."""
    with locked(tree):
        return subprocess.run(["ctest", *args], cwd=tree, capture_output=True, text=True, timeout=timeout_s)
