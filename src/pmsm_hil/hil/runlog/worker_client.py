"""`WorkerClient`: loop-side handle of a worker process fed through the shared-memory ring.

Shared by `RunLogger` (MCAP logger) and `LiveRerun` (live dashboard). The worker's entry point is
called as `target(notices, status, ring_path, ring_bytes, *args)`; messages are those of
`pmsm_hil.hil.runlog.channel`. Subclasses keep their own public API and turn failures into their
layer's exceptions.
"""

from __future__ import annotations

import contextlib
import importlib
import json
import multiprocessing
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from multiprocessing import resource_tracker, spawn
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pmsm_hil.hil.runlog import runner_watch
from pmsm_hil.hil.runlog.channel import NOTICE
from pmsm_hil.hil.runlog.ring import RingProducer

if TYPE_CHECKING:
    import numpy as np

_HELD = {signal.SIGINT, signal.SIGTERM}


@dataclass(frozen=True, slots=True)
class WorkerTarget:
    """A worker's target function named by its module and name: the parent pickles the two names only, so it need
    not import the module (the MCAP logger's: mcap's writer, zstandard, lz4, ≈ 0.08 CPU-s of every process that
    starts a logger); the worker imports it and calls it with the worker's arguments."""

    module: str
    name: str

    def __call__(self, *args: Any) -> None:
        getattr(importlib.import_module(self.module), self.name)(*args)


def _worker_entry(target: Callable[..., None], *args: Any) -> None:
    """The worker process's start: SIGTERM let through (it stops the worker), SIGINT left blocked (the runner
    owns Ctrl-C; the worker ignores it too). Once `target` returned (its file closed, its last status sent) the
    process ends at once, stdio flushed: the interpreter's teardown (0.5 s and more of wall time on a loaded
    machine) would only delay the runner's `close`, which waits for this process to end."""
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGTERM})
    if runner_watch.runner_pid() is None:  # spawned: the runner is the parent
        runner_watch.set_runner(os.getppid())
    target(*args)
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)


def _forked_worker_entry(environ: dict[str, str], umask: int, runner: int, target: Callable[..., None],
                         *args: Any) -> None:
    """`_worker_entry` for a worker forked from the fork server: first the runner's environment and umask of now, as
    a spawned worker inherits them (the fork server has those of its own start), and the runner's process id."""
    runner_watch.set_runner(runner)
    os.environ.clear()
    os.environ.update(environ)
    os.umask(umask)
    _worker_entry(target, *args)


def _umask() -> int:
    """This process's umask, read without setting it (Linux ≥ 4.7; else set and put back)."""
    with contextlib.suppress(OSError, StopIteration, ValueError):
        status = Path("/proc/self/status").read_text().splitlines()
        return int(next(line for line in status if line.startswith("Umask:")).split()[1], 8)
    mask = os.umask(0o22)
    os.umask(mask)
    return mask


_SPAWN_LOCK = threading.Lock()
_TRACKER_LOCK = threading.Lock()
#: how many workers this process has started (`start_method="auto"`: the first is spawned)
_started = 0
START_METHODS = ("auto", "spawn", "forkserver")


def resolve_start_method(start_method: str) -> str:
    """"spawn" or "forkserver" for a worker about to start: "auto" spawns a process's first worker (a `hil run`
    makes one: a fork server would only add a process) and forks the later ones from the logger's own fork server
    (`fork_server`)."""
    if start_method not in START_METHODS:
        raise ValueError(f"start_method: expected one of {', '.join(START_METHODS)}, got {start_method!r}")
    if start_method == "auto":
        return "forkserver" if _started else "spawn"
    return start_method


def _count_in_child() -> None:  # pragma: no cover - runs in a forked child
    """A forked child is a new process: its first worker is spawned again ("auto")."""
    global _started
    _started = 0


os.register_at_fork(after_in_child=_count_in_child)


@contextlib.contextmanager
def _main_not_rerun(target: Callable[..., None]) -> Iterator[None]:
    """While a worker starts: its start-up data do not name the parent's `__main__` script or module, so the new
    interpreter does not run it again (multiprocessing's spawn re-runs it, for a target defined there). The workers'
    targets are module functions: the `hil` console script's re-run imported the CLI, `pytest`'s `_pytest.config`,
    in every logger process. A target defined in `__main__` starts as multiprocessing does it."""
    original = getattr(spawn, "get_preparation_data", None)
    if original is None or getattr(target, "__module__", "__main__") == "__main__":
        yield
        return

    def without_main(name: str) -> dict[str, Any]:
        data: dict[str, Any] = original(name)
        data.pop("init_main_from_path", None)
        data.pop("init_main_from_name", None)
        return data

    with _SPAWN_LOCK:
        spawn.get_preparation_data = without_main
        try:
            yield
        finally:
            spawn.get_preparation_data = original


def _tracker_known() -> bool:
    """Whether this process has started (or was given) multiprocessing's resource tracker."""
    return getattr(resource_tracker._resource_tracker, "_fd", None) is not None


@contextlib.contextmanager
def _no_tracker_started() -> Iterator[None]:
    """While a worker is spawned: multiprocessing's spawn starts a resource tracker for the child to register shared
    memory and semaphores with (a process of its own importing multiprocessing: ≈ 0.05 CPU-s of every `hil run`).
    A worker makes neither (its ring is a file of its own, its pipes are pipes): where no tracker runs yet, the child
    is handed /dev/null as the tracker's pipe instead. A tracker already running is passed on as multiprocessing
    does."""
    if _tracker_known() or not callable(getattr(resource_tracker, "getfd", None)):
        yield
        return
    with _TRACKER_LOCK:
        devnull = os.open(os.devnull, os.O_WRONLY)
        original = resource_tracker.getfd
        resource_tracker.getfd = lambda: devnull
        try:
            yield
        finally:
            resource_tracker.getfd = original
            os.close(devnull)  # the child holds its own copy


#: how many start timeouts a worker that keeps using CPU may take to report ready
START_CEILING = 10


def _cpu_seconds(pid: int | None) -> float:
    """CPU time (s, user + system) process `pid` has used so far; 0 if it cannot be read (gone, not Linux)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return 0.0


def start_failure(timeout_s: float) -> str:
    """Why `_await_ready` gave up on a worker that neither died nor reported ready, for the error line."""
    return f"(no CPU used for {timeout_s:g} s, or not ready after {START_CEILING * timeout_s:g} s)"


class WorkerClient:
    """Ring, notice pipe, status pipe and worker process; `_error_prefix` is put before b"E" texts."""

    _error_prefix = ""

    def __init__(self) -> None:
        self._closed = True
        self.final_stats: dict[str, Any] | None = None
        self._error: str | None = None

    def _start_worker(self, target: Callable[..., None], args: tuple[Any, ...], *, name: str,
                      start_method: str, ring_bytes: int, stall_timeout_s: float) -> None:
        """Create the ring (`ring_bytes`) and the pipes and start the worker. An OSError from the start
        is re-raised after the ring is released. RunLogError if the ring cannot be created.

        Ctrl-C and SIGTERM wait (blocked) until the worker has started: one arriving while the ring is made
        (its 64 MiB are touched) left its file in /dev/shm, one arriving while the runner writes the worker's
        start-up data left a half-started child (an EOFError traceback); the child starts with both blocked,
        so a terminal's Ctrl-C never reaches its imports either (`_worker_entry`)."""
        self._stall_timeout_s = stall_timeout_s
        auto = start_method == "auto"
        start_method = resolve_start_method(start_method)
        if start_method != "spawn" or _tracker_known():
            resource_tracker.ensure_running()  # started first: starting it unblocks the signals again
        mask = signal.pthread_sigmask(signal.SIG_BLOCK, _HELD)
        try:
            if start_method == "forkserver":  # started with the signals blocked: so are the workers it forks
                from pmsm_hil.hil.runlog import fork_server  # not in the spawned worker (it imports this module)

                try:
                    fork_server.ensure_running()
                except OSError:  # e.g. a TMPDIR too long for the server's AF_UNIX address
                    if not auto:
                        raise
                    start_method = "spawn"  # "auto" only saves CPU: the logger is spawned as a first one is
            self._ring = RingProducer(ring_bytes)
            try:
                self._spawn(target, args, name=name, start_method=start_method, ring_bytes=ring_bytes)
            except BaseException:
                self._ring.close()
                raise
        finally:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # a signal held meanwhile arrives now
        self._closed = False

    def _spawn(self, target: Callable[..., None], args: tuple[Any, ...], *, name: str, start_method: str,
               ring_bytes: int) -> None:
        global _started
        ctx = multiprocessing.get_context(start_method)
        notice_r, self._notices = ctx.Pipe(duplex=False)
        self._status, status_w = ctx.Pipe(duplex=False)
        entry: Callable[..., None] = _worker_entry
        head: tuple[Any, ...] = ()
        serving: contextlib.AbstractContextManager[None] = contextlib.nullcontext()
        if start_method == "forkserver":
            from pmsm_hil.hil.runlog import fork_server

            entry, serving = _forked_worker_entry, fork_server.serving()
            head = (dict(os.environ), _umask(), os.getpid())
        self._proc: BaseProcess = ctx.Process(  # type: ignore[attr-defined]
            target=entry, name=name, daemon=True,
            args=(*head, target, notice_r, status_w, str(self._ring.path), ring_bytes, *args))
        try:
            untracked = _no_tracker_started() if start_method == "spawn" else contextlib.nullcontext()
            with _main_not_rerun(target), serving, untracked:
                self._proc.start()
            _started += 1
        finally:
            notice_r.close()
            status_w.close()

    def _start(self, target: Callable[..., None], args: tuple[Any, ...], *, name: str, start_method: str,
               ring_bytes: int, stall_timeout_s: float, start_timeout_s: float) -> bytes | None:
        """`_start_worker`, then `_await_ready`. Ctrl-C or SIGTERM anywhere in it (a signal held while the worker
        started arrives as soon as it has) leaves no process, pipe or ring file behind: `_abort()`, re-raised."""
        try:
            self._start_worker(target, args, name=name, start_method=start_method, ring_bytes=ring_bytes,
                               stall_timeout_s=stall_timeout_s)
            return self._await_ready(start_timeout_s)
        except BaseException:
            self._abort()
            raise

    def _await_ready(self, timeout_s: float) -> bytes | None:
        """Wait for b"R"; return the text after it, or None after `_abort()` (then `_error` holds the worker's
        message, if it sent one). The wait ends when the worker died, when it used no CPU for `timeout_s` (s) or
        after `START_CEILING` × `timeout_s` in all: a worker still importing on a starved machine (a VM under
        TCG beside other jobs took more than 60 s) is slow, not broken."""
        start = last_progress = time.monotonic()
        cpu = _cpu_seconds(self._proc.pid)
        while True:
            now = time.monotonic()
            used = _cpu_seconds(self._proc.pid)
            if used > cpu:
                cpu, last_progress = used, now
            if now - last_progress >= timeout_s or now - start >= START_CEILING * timeout_s:
                break
            if self._status.poll(0.05):
                msg = self._read_status()
                if msg is not None and msg[:1] == b"R":
                    self._ring.unlink()
                    return msg[1:]
                break
            if not self._proc.is_alive():
                break
        self._abort()
        return None

    def _read_status(self) -> bytes | None:
        """Receive one status message (None if the pipe is closed); records errors and final stats."""
        try:
            msg = self._status.recv_bytes()
        except (EOFError, OSError):
            return None
        if msg[:1] == b"E":
            self._error = self._error_prefix + msg[1:].decode(errors="replace")
        elif msg[:1] == b"D":
            self.final_stats = dict(json.loads(msg[1:]))
        return msg

    def _drain_status(self) -> None:
        """Read every status message already waiting."""
        while self._status.poll(0):
            if self._read_status() is None:
                break

    def _alive(self) -> bool:
        return self._proc.is_alive()

    def _push(self, kind: int, block: np.ndarray, itemsize: int) -> None:
        """Copy `block` into the ring in whole records (≤ a quarter of the ring each) and send a notice of
        `kind` per piece. Raises RunLogError if the ring stays full, OSError if the notice pipe broke."""
        import numpy as np  # not at the module's top: the worker process imports this module for `_worker_entry`

        payload = np.ascontiguousarray(block).view(np.uint8)
        step = max(1, self._ring.capacity // (4 * itemsize)) * itemsize
        for start in range(0, payload.shape[0], step):
            piece = payload[start : start + step]
            pos = self._ring.put(piece, self._alive, self._stall_timeout_s)
            self._notices.send_bytes(NOTICE.pack(kind, pos, piece.shape[0]))

    @property
    def stall_s(self) -> float:
        """Total time (s) submits waited for ring space because the worker was behind."""
        return float(self._ring.stall_s)

    def _stop_worker(self, close_kind: int, timeout_s: float) -> bool:
        """Send the close notice, wait up to `timeout_s` (s), then `_abort()`; True if the worker ended
        by itself within that time."""
        self._closed = True
        with contextlib.suppress(OSError):
            self._notices.send_bytes(NOTICE.pack(close_kind, 0, 0))
        self._proc.join(timeout_s)
        finished = not self._proc.is_alive()
        self._abort()
        return finished

    def _abort(self) -> None:
        """Collect the last status messages, stop the process if needed and release the pipes and ring (as far
        as `_start_worker` got)."""
        self._closed = True
        if not hasattr(self, "_proc"):  # stopped before the process was made: only the ring, if any
            with contextlib.suppress(Exception):
                self._ring.close()
            return
        self._drain_status()
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(5.0)
        if self._proc.is_alive():
            self._proc.kill()
            self._proc.join(5.0)
        with contextlib.suppress(OSError):
            self._notices.close()
            self._status.close()
        with contextlib.suppress(Exception):
            self._ring.close()
