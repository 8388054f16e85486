"""A worker process's start (`WorkerClient._await_ready`) is judged by its progress, not by wall time: one that keeps
using CPU past the start timeout still starts (a starved machine, a VM under TCG), one that uses no CPU for the
timeout is given up with the reason in one line, and nothing is left behind."""

from __future__ import annotations

import pickle
import time

from pmsm_hil.hil.runlog.sink import COMPRESSION_TYPES
from pmsm_hil.hil.runlog.topics import COMPRESSIONS
from pmsm_hil.hil.runlog.worker_client import START_CEILING, WorkerClient, WorkerTarget
from tests.runlog import _slow_workers

RING_BYTES = 1 << 16


class _Client(WorkerClient):
    def start(self, target: object, *args: object, timeout_s: float) -> bytes | None:
        return self._start(target, args, name="hil-test-worker",  # type: ignore[arg-type]
                           start_method="spawn", ring_bytes=RING_BYTES, stall_timeout_s=5.0,
                           start_timeout_s=timeout_s)


def test_a_worker_busy_past_the_start_timeout_still_starts() -> None:
    client = _Client()
    # busy for 2 s of wall time against a 1 s timeout (twice it: a spin of 3 s only burnt more CPU), within the 10 s
    # ceiling: it never stops progressing
    ready = client.start(_slow_workers.spin_then_ready, 2.0, timeout_s=1.0)
    try:
        assert ready == b""
        assert client._alive()
    finally:
        client._abort()
    assert not client._alive()


def test_a_worker_that_uses_no_cpu_is_given_up_after_the_timeout() -> None:
    client = _Client()
    t0 = time.monotonic()
    ready = client.start(_slow_workers.sleep_forever, timeout_s=0.5)
    waited = time.monotonic() - t0
    assert ready is None
    assert waited < START_CEILING * 0.5 + 30  # the ceiling bounds it even if the child's imports ran long
    assert not client._alive()  # aborted: no process left



def test_a_worker_named_by_module_and_function_starts_as_the_function_does() -> None:
    """`WorkerTarget`: the parent pickles two names (not the function, whose module it need not import); the worker
    imports the module and runs the function with its arguments."""
    target = WorkerTarget("tests.runlog._slow_workers", "spin_then_ready")
    assert pickle.loads(pickle.dumps(target)) == target and len(pickle.dumps(target)) < 200
    client = _Client()
    ready = client.start(target, 0.0, timeout_s=30.0)
    try:
        assert ready == b"" and client._alive()
    finally:
        client._abort()


def test_the_logger_takes_the_compressions_its_writer_writes() -> None:
    """`RunLogger` checks a compression by its name (without mcap's writer); the sink writes each of them."""
    assert sorted(COMPRESSIONS) == sorted(COMPRESSION_TYPES)
