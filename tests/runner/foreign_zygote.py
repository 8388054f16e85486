"""Foreign targets (foreign_target.py) forked from one process that has already imported python-can, cantools and the
`hilserial` link: each target is still a process of its own on its own port, the script run as `__main__` with the
same command line; only the interpreter's start-up and those imports (≈ 0.6 CPU-s a target) are made once per
pytest worker instead of once per test.

As a script it is the zygote: it reads commands on stdin, one per line, and answers one line on stdout each:
`start ARG...` (JSON list) forks a target and answers its pid; `reap PID` waits for that ended target and answers
its exit code and CPU seconds (user + system, from wait4). End of stdin ends the zygote (the worker has ended).
`start_target()` is the tests' side: a handle with Popen's poll, wait, send_signal, terminate and kill (a pidfd:
the target is the zygote's child, not the worker's)."""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn

if TYPE_CHECKING:
    from tests.zygote_client import ZygoteClient

HERE = Path(__file__).resolve().parent


def _serve() -> int:
    """The zygote's loop (see the module's docstring)."""
    import can.interfaces  # noqa: F401  - python-can and its interface table (its entry-point scan)
    import cantools  # noqa: F401

    from pmsm_hil.protocol.links import wire_bus  # noqa: F401  - the `hilserial` interface's module

    return serve(_target)


def serve(child: Callable[[Any], None]) -> int:
    """A zygote's loop on stdin: `start JSON` forks `child(decoded JSON)` (it never returns) and answers its pid,
    `reap PID` its exit code and CPU seconds (also tests/runner/hil_zygote.py's)."""
    for line in sys.stdin:
        command, _, arg = line.strip().partition(" ")
        if command == "start":
            spec = json.loads(arg)
            pid = os.fork()
            if pid == 0:
                child(spec)
            print(pid, flush=True)
        elif command == "reap":
            _, status, usage = os.wait4(int(arg), 0)
            print(os.waitstatus_to_exitcode(status), usage.ru_utime + usage.ru_stime, flush=True)
    return 0


def _target(argv: list[str]) -> None:
    """In the forked child: foreign_target.py run as `__main__` with `argv`, as `python foreign_target.py ARGV`
    would (stdin from /dev/null, stdout to the worker's stderr); never returns."""
    import runpy

    os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
    os.dup2(2, 1)
    script = str(HERE / "foreign_target.py")
    sys.argv = [script, *argv]

    def run() -> int:
        runpy.run_path(script, run_name="__main__")
        return 0

    exit_after(run)


def exit_after(run: Callable[[], int], *, exit_funcs: bool = False) -> NoReturn:
    """In a forked child: `run()`, then end the process with its exit code (a SystemExit's; 1 and the traceback on
    stderr for any other exception), the exit handlers run first with `exit_funcs`, the streams flushed."""
    import atexit
    import traceback

    code = 1
    try:
        code = run()
    except SystemExit as exc:
        code = exc.code if isinstance(exc.code, int) else int(exc.code is not None)
    except BaseException:
        traceback.print_exc()
    finally:
        if exit_funcs:
            atexit._run_exitfuncs()
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


def _zygote() -> ZygoteClient:
    """The worker's one zygote process (tests/zygote_client.py)."""
    global _CLIENT
    if _CLIENT is None:
        from tests.zygote_client import ZygoteClient  # the worker's side only: the zygote runs this file as a script

        _CLIENT = ZygoteClient(__file__, "foreign targets")
    return _CLIENT


_CLIENT: ZygoteClient | None = None


class ForeignTarget:
    """A foreign target forked by the zygote: what the tests use of subprocess.Popen. (`client`, `start`: another
    zygote of the same protocol and the line that starts its child, tests/runner/hil_zygote.py.)"""

    def __init__(self, argv: list[str], client: ZygoteClient | None = None, start: str | None = None) -> None:
        self._client = client or _zygote()
        self.pid = int(self._client.ask(start or "start " + json.dumps(argv)))
        self._pidfd = os.pidfd_open(self.pid)  # the zygote reaps it only when asked: a zombie is still this pid
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None and select.select([self._pidfd], [], [], 0)[0]:
            from tests import reaped_cpu  # not in the zygote: its script's folder is not the tests' root

            code, cpu = self._client.ask(f"reap {self.pid}").split()
            self.returncode = int(code)
            reaped_cpu.CPU_S.append(float(cpu))
            os.close(self._pidfd)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        if self.returncode is None and not select.select([self._pidfd], [], [], timeout)[0]:
            raise subprocess.TimeoutExpired(f"foreign target {self.pid}", timeout or 0.0)
        code = self.poll()
        assert code is not None
        return code

    def send_signal(self, sig: int) -> None:
        if self.returncode is None:
            signal.pidfd_send_signal(self._pidfd, sig)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


def start_target(*argv: str) -> ForeignTarget:
    """foreign_target.py with these arguments (PORT LOGFILE RULE=PERIOD ...), forked from the zygote."""
    return ForeignTarget(list(argv))


if __name__ == "__main__":
    sys.exit(_serve())
