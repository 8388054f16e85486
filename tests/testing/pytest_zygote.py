"""The pytest sessions of the suite's tests (tests/testing/pytest_session.py) forked from one process per pytest worker
that has already imported pytest and the third-party libraries every session loads (numpy, python-can, mcap): each
session is still a process of its own, `python -m pytest ARGS` from the repository root with its own environment,
stdin, stdout and stderr; only the interpreter's start-up and those imports are made once per worker instead of once
per session.

The package and pytest's plugins are imported by a collect-only session in the zygote (`_warm_up`): pytest marks
the modules of every plugin's distribution (pmsm_hil among them) for assertion rewriting when a session starts, and a
module imported otherwise would be neither rewritten nor silent in a session (`PytestAssertRewriteWarning`).
The test modules and conftest files are imported by each session itself, as a fresh `python -m pytest` does.

As a script it is the zygote: it reads commands on stdin, one per line, and answers one line on stdout each:
`start {"argv": [...], "env": {...}, "stdout": FILE, "stderr": FILE}` forks a session and answers its pid;
`reap PID` waits for that ended session and answers its exit code and CPU seconds (user + system, from wait4: the
session and every process it waited for). End of stdin ends the zygote (the worker has ended)."""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import threading
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from tests.zygote_client import ZygoteClient

ROOT = Path(__file__).resolve().parents[2]


def _serve() -> int:
    """The zygote's loop (see the module's docstring)."""
    sys.path[0] = os.getcwd()  # as `python -m pytest` started in the repository root
    import can.interfaces  # noqa: F401  - python-can and its interface table (its entry-point scan)
    import mcap.writer  # noqa: F401
    import numpy  # noqa: F401
    import pytest  # noqa: F401

    _warm_up()
    for line in sys.stdin:
        command, _, arg = line.strip().partition(" ")
        if command == "start":
            request = json.loads(arg)
            sys.stdout.flush()
            pid = os.fork()
            if pid == 0:
                raise SystemExit(_session(request))  # unwinds this loop: the interpreter ends as `python -m` does
            print(pid, flush=True)
        elif command == "reap":
            _, status, usage = os.wait4(int(arg), 0)
            print(os.waitstatus_to_exitcode(status), usage.ru_utime + usage.ru_stime, flush=True)
    return 0


def _warm_up() -> None:
    """One collect-only session of the conformance package, its output discarded: pytest's plugins (the entry
    points) and the package are imported as a session imports them (through pytest's assertion rewriting, so a
    session after it finds them rewritten and silent); the test modules and conftest files it imported are
    forgotten (each session imports its own)."""
    import shutil
    import tempfile

    import pytest

    saved = os.dup(1), os.dup(2)
    null = os.open(os.devnull, os.O_WRONLY)
    basetemp = tempfile.mkdtemp(prefix="hil-pytest-zygote-")  # never pytest's numbered folders (nor their pruning)
    try:
        for fd in (1, 2):
            os.dup2(null, fd)
        pytest.main(["-p", "no:cacheprovider", "-q", "-n", "0", "--co", f"--basetemp={basetemp}/t", "--pyargs",
                     "pmsm_hil.conformance"])
    finally:
        for fd, old in zip((1, 2), saved, strict=True):
            os.dup2(old, fd)
            os.close(old)
        os.close(null)
        shutil.rmtree(basetemp, ignore_errors=True)
    for name in [n for n in sys.modules if n.rpartition(".")[2].startswith(("test_", "conftest"))]:
        del sys.modules[name]
    assert threading.active_count() == 1, threading.enumerate()  # a fork keeps only the thread that forks


def _session(request: dict[str, Any]) -> int | str:
    """In the forked child: `python -m pytest ARGV` (pytest's console entry, as `pytest/__main__.py` runs it) with the
    request's environment, stdin from /dev/null, stdout and stderr to the request's files."""
    import pytest
    from _pytest.config import _console_main

    os.environ.clear()
    os.environ.update(request["env"])
    os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
    for fd, name in ((1, "stdout"), (2, "stderr")):
        os.dup2(os.open(request[name], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644), fd)
    sys.argv = [str(Path(pytest.__file__).with_name("__main__.py")), *request["argv"]]
    return _console_main()


def _zygote() -> ZygoteClient:
    """The worker's one zygote process (tests/zygote_client.py)."""
    global _CLIENT
    if _CLIENT is None:
        from tests.zygote_client import ZygoteClient  # the worker's side only: the zygote runs this file as a script

        _CLIENT = ZygoteClient(__file__, "pytest sessions", cwd=ROOT)
    return _CLIENT


_CLIENT: ZygoteClient | None = None


def run_session(argv: list[str], env: dict[str, str], stdout: Path, stderr: Path, timeout_s: float) -> int:
    """`python -m pytest ARGV` forked from the zygote, its output into the two files; its exit code (the session
    killed and subprocess.TimeoutExpired raised after `timeout_s` of wall time, as subprocess.run does). Its CPU
    goes to the per-test report (tests/reaped_cpu.py)."""
    from tests import reaped_cpu

    request = {"argv": argv, "env": env, "stdout": str(stdout), "stderr": str(stderr)}
    pid = int(_zygote().ask("start " + json.dumps(request), env))
    pidfd = os.pidfd_open(pid)  # the zygote reaps it only when asked: a zombie is still this pid
    try:
        ended = bool(select.select([pidfd], [], [], timeout_s)[0])
        if not ended:
            signal.pidfd_send_signal(pidfd, signal.SIGKILL)
        code, cpu = _zygote().ask(f"reap {pid}", env).split()
        reaped_cpu.CPU_S.append(float(cpu))
    finally:
        os.close(pidfd)
    if not ended:
        raise subprocess.TimeoutExpired(["python", "-m", "pytest", *argv], timeout_s)
    return int(code)


if __name__ == "__main__":
    sys.exit(_serve())
