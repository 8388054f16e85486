"""The run-log workers' own fork server, for a process that makes many logged runs (a pytest session, `hil.run`
in a loop, in-process sweep points): a process that has imported the logger's modules once and forks a worker
per run. A spawned logger costs ≈ 0.2 CPU-s (a new interpreter and its imports), one forked from here ≈ 0.015.

It is multiprocessing's fork server, but an instance of its own, not the process-wide one a sweep's pool sets up
with its own modules, environment and signal handling (`pmsm_hil.app.sweep.engines`). `WorkerClient` starts it
with SIGINT and SIGTERM blocked, so it and the workers it forks start with them blocked, as a spawned worker does;
it ends when every process holding its "alive" pipe (the one that started it) has ended. A process forked from
one that started it starts a fork server of its own when it needs one."""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Iterator
from multiprocessing import forkserver

#: what the fork server imports before it forks (a worker's whole start-up, but the pipes and the ring)
PRELOAD = ["pmsm_hil.hil.runlog.worker_client", "pmsm_hil.hil.runlog.worker"]

_LOCK = threading.Lock()
_SERVING = threading.Lock()
_server: forkserver.ForkServer | None = None


def ensure_running() -> None:
    """Start the fork server unless it is running (again after it died)."""
    global _server
    with _LOCK:
        if _server is None:
            _server = forkserver.ForkServer()
            _server.set_forkserver_preload(PRELOAD)
        _server.ensure_running()


def pid() -> int | None:
    """The fork server's process id, None before it was started in this process."""
    return None if _server is None else _server._forkserver_pid  # type: ignore[attr-defined]


@contextlib.contextmanager
def serving() -> Iterator[None]:
    """While a process of the "forkserver" context starts: it is forked by this fork server, not the process-wide
    one (multiprocessing's forkserver Popen asks the module's `connect_to_new_process`); one start at a time."""
    ensure_running()
    assert _server is not None
    with _SERVING:
        original = forkserver.connect_to_new_process
        forkserver.connect_to_new_process = _server.connect_to_new_process
        try:
            yield
        finally:
            forkserver.connect_to_new_process = original


def _forget_in_child() -> None:
    """In a child forked from a process that started the fork server: that server is not the child's to use (it is
    not its child; its "alive" pipe is closed here so the server still ends with its starter)."""
    global _server
    if _server is not None:
        alive = _server._forkserver_alive_fd  # type: ignore[attr-defined]
        if alive is not None:
            with contextlib.suppress(OSError):
                os.close(alive)
    _server = None


os.register_at_fork(after_in_child=_forget_in_child)
