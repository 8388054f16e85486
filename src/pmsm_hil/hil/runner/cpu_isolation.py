"""Keep the real-time loop's CPU for the loop (`--cpu`): the run's other threads and its logger process are
moved off that CPU for the run and put back afterwards."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterable


def _threads(pid: int) -> list[int]:
    """Thread ids of process `pid` (none if it is gone)."""
    try:
        return [int(name) for name in os.listdir(f"/proc/{pid}/task")]
    except OSError:
        return []


def isolate_cpu(cpu: int, pids: Iterable[int] = ()) -> Callable[[], None]:
    """Move every thread of this process and of `pids` off CPU `cpu`; returns the function that restores their
    CPU masks. Threads started later inherit their creator's mask (the native loop's thread then pins itself to
    `cpu`). What the system refuses is left as it is: the loop still runs, its lateness shows the cost."""
    saved: list[tuple[int, set[int]]] = []
    for pid in (os.getpid(), *pids):
        for tid in _threads(pid):
            try:
                mask = os.sched_getaffinity(tid)
                others = mask - {cpu}
                if others and others != mask:
                    os.sched_setaffinity(tid, others)
                    saved.append((tid, mask))
            except OSError:
                continue

    def restore() -> None:
        for tid, mask in saved:
            with contextlib.suppress(OSError):
                os.sched_setaffinity(tid, mask)

    return restore
