"""C built with the host's compiler for the tests (firmware sources checked on the host)."""

from __future__ import annotations

import ctypes
import shutil
import subprocess
from collections.abc import Sequence
from pathlib import Path

import pytest

#: the project's strict C flags
STRICT = ("-std=c99", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion")


def host_cc() -> str:
    """The host C compiler (cc, else gcc); the test is skipped without one."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no host C compiler (cc) installed")
    return cc


def compile_c(out: Path, args: Sequence[str]) -> Path:
    """`cc ARGS -o OUT` (flags, sources, libraries); fails the test with the compiler's message."""
    proc = subprocess.run([host_cc(), *args, "-o", str(out)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return out


def shared_library(out: Path, args: Sequence[str]) -> ctypes.CDLL:
    """The shared library OUT built from ARGS (position-independent), loaded."""
    return ctypes.CDLL(str(compile_c(out, ["-shared", "-fPIC", *args])))
