"""`hil` commands forked from one process that has already imported the package (its CLI, the runner, the logger
and numpy): each command is still a process of its own, run as `python -m pmsm_hil.app.cli.main ARGV` would be,
with its own session when asked (a terminal's Ctrl-C to its process group), stderr to a file; only the
interpreter's start-up and those imports (≈ 0.6 CPU-s a command) are made once per pytest worker. For the tests
that signal a run mid-way (tests/runner/test_interrupt_log.py): the first second of `hil`, when its imports run,
is still tested with fresh processes.

As a script it is the zygote (the protocol of tests/runner/foreign_zygote.py): `start JSON` ({"argv", "stderr",
"session"}) forks a command and answers its pid; `reap PID` waits for it and answers its exit code and CPU seconds.
`start_hil()` is the tests' side: a handle with what the tests use of Popen (tests/runner/foreign_zygote.py)."""

from __future__ import annotations

import json
import os
import signal
import sys
from pathlib import Path
from typing import TYPE_CHECKING, NoReturn

if TYPE_CHECKING:
    from tests.runner.foreign_zygote import ForeignTarget
    from tests.zygote_client import ZygoteClient


def _serve() -> int:
    """The zygote's loop (see the module's docstring)."""
    import numpy  # noqa: F401
    from foreign_zygote import serve  # the zygote runs as a script: this folder is on its path

    import pmsm_hil.app.cli.main
    import pmsm_hil.hil.runlog.logger
    import pmsm_hil.hil.runner.run  # noqa: F401

    return serve(lambda spec: _command(spec["argv"], spec["stderr"], spec["session"]))


def _command(argv: list[str], stderr: str, session: bool) -> NoReturn:
    """In the forked child: `hil ARGV` as `python -m pmsm_hil.app.cli.main` runs it (SIGINT and SIGTERM as a fresh
    interpreter has them, stdin and stdout /dev/null, stderr to the file `stderr`, its exit handlers run at the
    end); never returns."""
    from foreign_zygote import exit_after  # in the zygote: this folder is on its path

    from pmsm_hil.app.cli.main import main

    if session:
        os.setsid()
    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    os.dup2(os.open(os.devnull, os.O_RDONLY), 0)
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)
    os.dup2(os.open(stderr, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644), 2)
    sys.argv = ["hil", *argv]
    exit_after(lambda: main(argv), exit_funcs=True)


def _zygote() -> ZygoteClient:
    """The worker's one `hil` zygote process (tests/zygote_client.py)."""
    global _CLIENT
    if _CLIENT is None:
        from tests.zygote_client import ZygoteClient  # the worker's side only: the zygote runs this file as a script

        _CLIENT = ZygoteClient(__file__, "hil commands", cwd=Path(__file__).resolve().parents[2])
    return _CLIENT


_CLIENT: ZygoteClient | None = None


def start_hil(argv: list[str], stderr: Path, *, session: bool = False) -> ForeignTarget:
    """`hil ARGV` forked from the zygote, its stderr to the file `stderr`, in a session of its own with `session`
    (its pid is then its process group's id)."""
    from tests.runner.foreign_zygote import ForeignTarget

    spec = {"argv": argv, "stderr": str(stderr), "session": session}
    return ForeignTarget(argv, _zygote(), "start " + json.dumps(spec))


if __name__ == "__main__":
    sys.exit(_serve())
