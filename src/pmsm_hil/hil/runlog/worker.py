"""Main function of the logger process: take notices from the runner, write MCAP, flush periodically.

Ends on a close notice, on EOF of the notice pipe or a change of parent process (the runner died: the
file is finalised anyway). SIGTERM ends it too, once the notices have been idle for `SIGTERM_IDLE_S` while the
runner slept (`runner_watch`): a SIGTERM sent to the whole process group (`kill -- -PGID`, a job scheduler)
reaches the runner as well, which drains its loop into the logger and closes it; the blocks still on their way
are written, not dropped, however long a busy machine keeps the runner from a CPU.
SIGINT is ignored: the runner owns Ctrl-C and calls `RunLogger.close()`.
Status messages to the runner: b"R" ready, b"E" + text fatal error, b"D" + JSON final statistics.
"""

from __future__ import annotations

import json
import os
import signal
import sys
import time
from multiprocessing.connection import Connection
from pathlib import Path
from types import FrameType
from typing import Any, Final

from pmsm_hil.hil.runlog import topics
from pmsm_hil.hil.runlog.channel import NOTICE, send_status
from pmsm_hil.hil.runlog.errors import RunLogError
from pmsm_hil.hil.runlog.ring import RingConsumer
from pmsm_hil.hil.runlog.runner_watch import RunnerIdle, runner_pid
from pmsm_hil.hil.runlog.sink import McapSink

MAX_POLL_S: Final = 0.2


def run_worker(
    notices: Connection,
    status: Connection,
    ring_path: str,
    ring_bytes: int,
    path: str,
    metadata: dict[str, str],
    flush_interval_s: float,
    compression: str,
    trace_fields: tuple[str, ...],
) -> None:
    """Logger process entry point (see module docstring)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    stop: list[str] = []
    idle = RunnerIdle(runner_pid())  # since the last notice, or SIGTERM if later

    def on_term(signum: int, frame: FrameType | None) -> None:
        stop.append("sigterm")
        idle.reset()

    signal.signal(signal.SIGTERM, on_term)
    try:
        ring = RingConsumer(Path(ring_path), ring_bytes)
        sink = McapSink(Path(path), metadata, compression, tuple(trace_fields))
    except Exception as exc:  # report any setup failure to the runner instead of a traceback
        send_status(status, b"E" + f"run logger: cannot open {path}: {exc}".encode())
        return
    send_status(status, b"R")
    stats: dict[str, Any] = {"reason": "close", "busy_s": 0.0, "flushes": 0}
    writers = {
        topics.KIND_PERIODS: sink.write_periods,
        topics.KIND_FRAMES: sink.write_frames,
        topics.KIND_TRACE: sink.write_trace,
        topics.KIND_FAULTS: sink.write_faults,
        topics.KIND_CONSOLE: sink.write_console,
        topics.KIND_BOARD: sink.write_board,
    }
    next_flush = time.monotonic() + flush_interval_s
    parent = os.getppid()
    try:
        while not stop or not idle.over():
            timeout = min(max(next_flush - time.monotonic(), 0.0), MAX_POLL_S)
            if not notices.poll(timeout):
                if os.getppid() != parent:  # runner gone but a forked process still holds the pipe
                    stats["reason"] = "parent gone"
                    break
            else:
                idle.reset()
                try:
                    raw = notices.recv_bytes()
                except (EOFError, OSError):
                    stats["reason"] = "eof"
                    break
                kind, pos, nbytes = NOTICE.unpack(raw)
                if kind == topics.KIND_CLOSE:
                    break
                start = time.perf_counter()
                writers[kind](ring.take(pos, nbytes))
                stats["busy_s"] += time.perf_counter() - start
            if time.monotonic() >= next_flush:
                sink.flush()
                stats["flushes"] += 1
                next_flush = time.monotonic() + flush_interval_s
        if stop and stats["reason"] == "close":
            stats["reason"] = stop[0]
    except OSError as exc:  # a full disk: the file ends as a valid MCAP at its last complete record
        stats["reason"] = "error"
        send_status(status, b"E" + f"run logger: {sink.abandon(exc)}".encode())
    except Exception as exc:  # keep the data written so far; tell the runner
        stats["reason"] = "error"
        send_status(status, b"E" + f"run logger: {type(exc).__name__}: {exc}".encode())
    finally:
        try:
            sink.close()
        except RunLogError as exc:  # the summary did not fit (the file ends as `abandon` says)
            stats["reason"] = "error"
            send_status(status, b"E" + f"run logger: {exc}".encode())
        finally:
            ring.close()
    stats.update(sink.counts)
    stats["numpy"] = "numpy" in sys.modules  # whether this run's writes needed it (`sink.PURE_CPU_S`)
    send_status(status, b"D" + json.dumps(stats).encode())
