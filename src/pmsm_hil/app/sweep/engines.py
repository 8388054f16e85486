"""Engines that run independent tasks in parallel: in this process, a local process pool, Dask or Ray.

Every engine runs `fn(item)` for each item and yields `(index, result, error)` as tasks finish, in any
order; `error` is None or one line saying why the task gave no result (its worker died, the engine lost
it). `fn` must be a module-level function and items picklable: Dask and Ray send them by reference to
worker processes, possibly on other machines, which must have the same pmsm-hil installed. Results
(rows, small) come back through the engine; files a task writes go wherever its item says (a shared store).

- `inline`: this process, one task at a time (the library default, used by tests and `--workers 0`).
- `local`: a process pool of `workers` processes (default: every core), forkserver start, one task in
  flight per process; a worker that dies is reported for the tasks it was running and the pool restarted.
- `dask`: `Client(address)`, or a LocalCluster of `workers` single-threaded worker processes.
- `ray`: `ray.init(address=...)`, or a local Ray instance with `workers` CPUs (an instance already started
  in this process is reused and left running; one started by `init_local_ray` needs no per-task environment).
"""

from __future__ import annotations

import contextlib
import importlib
import logging
import multiprocessing
import os
import signal
import uuid
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import forkserver
from typing import Any

from pmsm_hil.hil.errors import ParameterError

ENGINES = ("local", "dask", "ray", "inline")
#: modules a local pool's fork server imports once, so each worker starts with them loaded
_PRELOAD = ["pmsm_hil.app.sweep.task", "pmsm_hil.hil.runner.run", "pmsm_hil.app.compare.runs"]

Outcome = tuple[int, Any, str | None]

#: environment variables that set the thread count of numpy's BLAS (OpenBLAS reads them in this order)
BLAS_THREAD_VARS = ("OPENBLAS_NUM_THREADS", "GOTO_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def blas_threads() -> str:
    """The BLAS thread count of this process: the first of BLAS_THREAD_VARS that is set, else the core count
    (OpenBLAS's default)."""
    for name in BLAS_THREAD_VARS[:3]:
        if os.environ.get(name):
            return os.environ[name]
    return str(os.cpu_count() or 1)


def blas_env() -> dict[str, str]:
    """Environment that gives a worker the coordinator's BLAS thread count.

    Metrics reduce long arrays with numpy dot products, which OpenBLAS splits across its threads: the last
    bits of a sum depend on the thread count. Dask and Ray start workers with 1 thread, a process pool
    inherits the machine's default; every engine gets this environment instead, so a run's metrics are
    bit-identical on every engine and worker count, and equal to `hil run` on the coordinating machine."""
    n = blas_threads()
    return dict.fromkeys(BLAS_THREAD_VARS, n)


class Engine:
    """Base: `workers` parallel slots; `map_unordered`; `close(abort)`; a context manager."""

    name = "engine"
    workers = 1
    #: a line to warn with after opening (None: nothing to say)
    warning: str | None = None

    def map_unordered(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[Outcome]:
        raise NotImplementedError

    def close(self, abort: bool = False) -> None:
        """Release the workers; `abort`: stop tasks still running now (after Ctrl-C)."""

    def describe(self) -> str:
        return f"{self.name} ({self.workers} worker{'s' if self.workers != 1 else ''})"

    def __enter__(self) -> Engine:
        return self

    def __exit__(self, exc_type: object, exc: object, tb: object) -> None:
        self.close(abort=exc_type is not None)


class InlineEngine(Engine):
    """Tasks one after the other in this process."""

    name = "inline"

    def map_unordered(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[Outcome]:
        for i, item in enumerate(items):
            yield i, fn(item), None


def _worker_init() -> None:
    """A pool worker ignores Ctrl-C (the terminal sends it to the whole group): the coordinator decides."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class LocalEngine(Engine):
    """A process pool on this machine."""

    name = "local"

    def __init__(self, workers: int | None = None) -> None:
        self.workers = workers or os.cpu_count() or 1
        self._pool: ProcessPoolExecutor | None = None

    def _new_pool(self) -> ProcessPoolExecutor:
        ctx = multiprocessing.get_context("forkserver")
        ctx.set_forkserver_preload(_PRELOAD)
        saved = dict(os.environ)
        os.environ.update(blas_env())  # the fork server (and so every worker) starts with it
        try:
            forkserver.ensure_running()
        finally:
            os.environ.clear()
            os.environ.update(saved)
        return ProcessPoolExecutor(self.workers, mp_context=ctx, initializer=_worker_init)

    def map_unordered(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[Outcome]:
        pending = deque(enumerate(items))
        running: dict[Future[Any], int] = {}
        while pending or running:
            if self._pool is None:
                self._pool = self._new_pool()
            while pending and len(running) < self.workers:
                i, item = pending.popleft()
                running[self._pool.submit(fn, item)] = i
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            broken = False
            for fut in done:
                i = running.pop(fut)
                try:
                    yield i, fut.result(), None
                except BrokenProcessPool as exc:
                    broken = True
                    yield i, None, f"worker process died ({exc})"
                except Exception as exc:  # the task function itself failed: that task's outcome
                    yield i, None, f"{type(exc).__name__}: {exc}"
            if broken:
                self.close(abort=True)

    def close(self, abort: bool = False) -> None:
        pool, self._pool = self._pool, None
        if pool is None:
            return
        if abort:
            processes = list(getattr(pool, "_processes", {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            for proc in processes:
                with contextlib.suppress(OSError, ValueError):
                    proc.kill()
        pool.shutdown(wait=True, cancel_futures=True)


def _missing(engine: str, module: str) -> ParameterError:
    return ParameterError(f"--engine {engine}: {module} is not installed (pip install -e \".[{engine}]\")")


class DaskEngine(Engine):
    """Dask distributed: the scheduler at `address`, or a LocalCluster started here."""

    name = "dask"

    def __init__(self, workers: int | None = None, address: str | None = None) -> None:
        try:
            distributed: Any = importlib.import_module("dask.distributed")
        except ImportError:
            raise _missing("dask", "dask.distributed") from None
        self._distributed = distributed
        Client, LocalCluster = distributed.Client, distributed.LocalCluster
        self._cluster: Any = None
        if address:
            try:
                self._client = Client(address, timeout=30)
            except OSError as exc:
                raise ParameterError(f"--address {address}: no Dask scheduler there ({exc})") from None
        else:
            # set before a worker process starts (numpy reads it once): the nannies' pre-spawn environment
            importlib.import_module("dask").config.set(
                {f"distributed.nanny.pre-spawn-environ.{k}": v for k, v in blas_env().items()})
            self._cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                                         processes=True, dashboard_address=None, silence_logs=logging.ERROR)
            self._client = Client(self._cluster)
        self.workers = max(1, sum(self._client.nthreads().values()))
        self._futures: list[Any] = []
        if address:
            theirs = set(self._client.run(blas_threads).values())
            if theirs != {blas_threads()}:
                self.warning = (f"the Dask workers use {'/'.join(sorted(theirs))} BLAS thread(s), this machine "
                                f"{blas_threads()}: metrics may differ from local runs in their last bits (start the "
                                "workers with OPENBLAS_NUM_THREADS set, docs/sweeps.md)")

    def map_unordered(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[Outcome]:
        as_completed = self._distributed.as_completed
        tag = uuid.uuid4().hex[:8]
        keys = [f"hil-{tag}-{i}" for i in range(len(items))]
        self._futures = self._client.map(fn, list(items), key=keys, pure=False, retries=0)
        index = {f.key: i for i, f in enumerate(self._futures)}
        for fut in as_completed(self._futures):
            i = index[fut.key]
            if fut.status == "finished":
                yield i, fut.result(), None
            else:
                yield i, None, f"dask: {fut.exception()!r}"
        self._futures = []

    def close(self, abort: bool = False) -> None:
        if abort and self._futures:
            with contextlib.suppress(Exception):
                self._client.cancel(self._futures, force=True)
        with contextlib.suppress(Exception):
            self._client.close()
        if self._cluster is not None:
            with contextlib.suppress(Exception):
                self._cluster.close()
            self._cluster = None


#: (node id, BLAS environment) of the local Ray instance `init_local_ray` started last: its workers inherited it
_local_ray: tuple[str, dict[str, str]] | None = None


def init_local_ray(ray: Any, workers: int | None = None, **kwargs: Any) -> None:
    """`ray.init` of a local instance of `workers` CPUs (default: every core) whose raylet, and so every worker,
    starts with `blas_env()`: its tasks need no per-task `runtime_env`, for which Ray would start dedicated worker
    processes beside the ones it started already (≈ 5 s and two Python processes at load 10)."""
    global _local_ray
    env = blas_env()
    saved = dict(os.environ)
    os.environ.update(env)
    try:
        ray.init(num_cpus=workers or os.cpu_count() or 1, **kwargs)
    finally:
        os.environ.clear()
        os.environ.update(saved)
    _local_ray = (ray.get_runtime_context().get_node_id(), env)


def ray_workers_inherit(ray: Any, env: dict[str, str]) -> bool:
    """Whether the running Ray instance is the local one `init_local_ray` started with `env`."""
    return _local_ray is not None and _local_ray == (ray.get_runtime_context().get_node_id(), env)


class RayEngine(Engine):
    """Ray: the cluster at `address` (`auto`: the local `ray start --head`), or a local instance."""

    name = "ray"

    def __init__(self, workers: int | None = None, address: str | None = None) -> None:
        try:
            ray: Any = importlib.import_module("ray")
        except ImportError:
            raise _missing("ray", "ray") from None
        self._ray = ray
        self._started = False
        if not ray.is_initialized():
            kwargs: dict[str, Any] = {"include_dashboard": False, "logging_level": logging.ERROR,
                                      "log_to_driver": False}
            try:
                if address:
                    ray.init(address=address, **kwargs)
                else:
                    init_local_ray(ray, workers, **kwargs)
            except ConnectionError as exc:
                raise ParameterError(f"--address {address}: no Ray cluster there ({exc})") from None
            self._started = True
        self.workers = max(1, int(ray.cluster_resources().get("CPU", 1)))
        self._pending: list[Any] = []

    def map_unordered(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> Iterator[Outcome]:
        ray = self._ray
        env = blas_env()
        remote = ray.remote(num_cpus=1, max_retries=0)(fn)
        if not ray_workers_inherit(ray, env):  # another instance or cluster: its workers get the env per task
            remote = remote.options(runtime_env={"env_vars": env})
        refs = {remote.remote(item): i for i, item in enumerate(items)}
        self._pending = list(refs)
        while self._pending:
            done, self._pending = ray.wait(self._pending, num_returns=1)
            for ref in done:
                try:
                    yield refs[ref], ray.get(ref), None
                except ray.exceptions.RayError as exc:
                    yield refs[ref], None, f"ray: {str(exc).strip().splitlines()[0]}"

    def close(self, abort: bool = False) -> None:
        if abort:
            for ref in self._pending:
                with contextlib.suppress(Exception):
                    self._ray.cancel(ref, force=True)
        self._pending = []
        if self._started:
            self._ray.shutdown()
            self._started = False


def open_engine(name: str, *, workers: int | None = None, address: str | None = None) -> Engine:
    """The engine called `name`; ParameterError naming the option for a bad combination or a missing extra."""
    if name not in ENGINES:
        raise ParameterError(f"--engine must be one of {', '.join(ENGINES)}, got {name!r}")
    if address and name in ("local", "inline"):
        raise ParameterError(f"--address: only for --engine dask or ray, not {name}")
    if address and workers:
        raise ParameterError("--workers: sizes a cluster started here; the cluster at --address has its own workers")
    if workers == 0 and name not in ("local", "inline"):
        raise ParameterError(f"--workers 0 (runs in this process): only with --engine local, not {name}")
    if name == "inline" or (name == "local" and workers == 0):
        return InlineEngine()
    if name == "local":
        return LocalEngine(workers)
    if name == "dask":
        return DaskEngine(workers, address)
    return RayEngine(workers, address)


__all__ = ["ENGINES", "DaskEngine", "Engine", "InlineEngine", "LocalEngine", "RayEngine", "open_engine"]
