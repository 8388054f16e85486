"""The MCAP logger of a process's later runs is forked from the logger's own fork server (`start_method="auto"`,
`pmsm_hil.hil.runlog.fork_server`), not spawned: the same bytes in the file, the same signal mask, and it still
finalises its file when the runner is killed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.hil.records import FRAME_DTYPE, PERIOD_DTYPE
from pmsm_hil.hil.runlog import fork_server, worker_client
from pmsm_hil.hil.runlog.errors import RunLogError
from pmsm_hil.hil.runlog.logger import RunLogger
from pmsm_hil.hil.runlog.reader import read_frames, read_periods

RING = 4 << 20


def _blocks() -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    periods = np.frombuffer(rng.bytes(300 * PERIOD_DTYPE.itemsize), PERIOD_DTYPE).copy()
    frames = np.frombuffer(rng.bytes(500 * FRAME_DTYPE.itemsize), FRAME_DTYPE).copy()
    for block in (periods, frames):  # random floats, but no NaN (compared through the reader below)
        for name in block.dtype.names or ():
            if block.dtype[name].kind == "f":
                block[name] = rng.standard_normal(block[name].shape)
    return periods, frames


def _status(pid: int, key: str) -> str:
    return next(line.split()[1] for line in Path(f"/proc/{pid}/status").read_text().splitlines()
                if line.startswith(key + ":"))


def _write(path: Path, start_method: str) -> tuple[int, str]:
    """Log the blocks; the logger's parent pid and signal mask (blocked) while it runs."""
    periods, frames = _blocks()
    with RunLogger(path, metadata={"run": "x"}, start_method=start_method, ring_bytes=RING) as lg:
        lg.submit_periods(periods)
        lg.submit_frames(frames)
        pid = lg._proc.pid
        assert pid is not None
        ppid = int(Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[1])
        mask = _status(pid, "SigBlk")
    return ppid, mask


def test_a_forked_logger_writes_the_bytes_a_spawned_one_writes(tmp_path: Path) -> None:
    spawned, forked = tmp_path / "spawned.mcap", tmp_path / "forked.mcap"
    ppid_s, mask_s = _write(spawned, "spawn")
    ppid_f, mask_f = _write(forked, "forkserver")
    assert ppid_s == os.getpid() and ppid_f == fork_server.pid() != os.getpid()
    assert mask_f == mask_s  # SIGINT still blocked in the worker, SIGTERM let through (worker_client._worker_entry)
    assert forked.read_bytes() == spawned.read_bytes()
    periods, frames = _blocks()
    assert read_periods(forked).tobytes() == periods.tobytes()
    assert read_frames(forked)["arbitration_id"].tolist() == frames["arbitration_id"].tolist()


def test_auto_spawns_a_process_first_logger_and_forks_the_later_ones(tmp_path: Path,
                                                                     monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(worker_client, "_started", 0)  # as in a new process
    first, _ = _write(tmp_path / "a.mcap", "auto")
    second, _ = _write(tmp_path / "b.mcap", "auto")
    assert first == os.getpid() and second == fork_server.pid()
    with pytest.raises(RunLogError, match="start_method: expected one of auto, spawn, forkserver, got 'fork'"):
        RunLogger(tmp_path / "c.mcap", metadata={}, start_method="fork")


def test_a_forked_child_neither_uses_its_parents_fork_server_nor_counts_its_workers(tmp_path: Path) -> None:
    _write(tmp_path / "a.mcap", "forkserver")
    assert fork_server.pid() is not None and worker_client._started > 0
    pid = os.fork()
    if pid == 0:  # pragma: no cover - the child
        os._exit(0 if fork_server.pid() is None and worker_client._started == 0 else 1)
    assert os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]) == 0


_LONG_TMPDIR_RUNNER = """
import sys
from pathlib import Path
from pmsm_hil.hil.runlog import fork_server
from pmsm_hil.hil.runlog.logger import RunLogger
for name in ("a", "b"):  # the second would be forked: its server's socket cannot be made in this TMPDIR
    with RunLogger(Path(sys.argv[1]) / (name + ".mcap"), metadata={}, ring_bytes=4 << 20) as lg:
        pid = lg._proc.pid
print(fork_server.pid(), flush=True)
"""


def test_auto_spawns_the_logger_when_the_fork_server_cannot_start(tmp_path: Path) -> None:
    """A TMPDIR too long for an AF_UNIX address (108 bytes) keeps the fork server from starting: "auto" spawns the
    later loggers as the first (it failed every later run with "AF_UNIX path too long" before)."""
    long_tmp = tmp_path / ("t" * 60) / ("u" * 60)
    long_tmp.mkdir(parents=True)
    done = subprocess.run([sys.executable, "-c", _LONG_TMPDIR_RUNNER, str(tmp_path)], capture_output=True, text=True,
                          timeout=120, env={**os.environ, "TMPDIR": str(long_tmp)}, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    for name in ("a", "b"):
        assert read_periods(tmp_path / f"{name}.mcap").shape[0] == 0
    (tmp_path / "named").mkdir()
    named = _LONG_TMPDIR_RUNNER.replace("ring_bytes=4 << 20", "ring_bytes=4 << 20, start_method='forkserver'")
    done = subprocess.run([sys.executable, "-c", named, str(tmp_path / "named")], capture_output=True, text=True,
                          timeout=120, env={**os.environ, "TMPDIR": str(long_tmp)}, check=False)
    assert done.returncode != 0 and "AF_UNIX path too long" in done.stderr  # asked for by name: the caller's error


_KILLED_RUNNER = """
import sys, time
from pathlib import Path
import numpy as np
from pmsm_hil.hil.records import PERIOD_DTYPE
from pmsm_hil.hil.runlog.logger import RunLogger
with RunLogger(Path(sys.argv[1]) / "first.mcap", metadata={}) as lg:
    pass
lg = RunLogger(Path(sys.argv[1]) / "second.mcap", metadata={}, ring_bytes=4 << 20)
lg.submit_periods(np.zeros(250, PERIOD_DTYPE))
print(lg._proc.pid, flush=True)
time.sleep(600)
"""


def test_a_forked_logger_finalises_its_file_when_the_runner_is_killed(tmp_path: Path) -> None:
    """The runner SIGKILLed with a forked logger open (its parent is the fork server, not the runner): the notice
    pipe's end ends the logger, which finalises the file with every period it was given."""
    runner = subprocess.Popen([sys.executable, "-c", _KILLED_RUNNER, str(tmp_path)], stdout=subprocess.PIPE,
                              text=True)
    assert runner.stdout is not None
    logger = int(runner.stdout.readline())
    assert int(Path(f"/proc/{logger}/stat").read_text().rsplit(")", 1)[1].split()[1]) != runner.pid
    runner.send_signal(signal.SIGKILL)
    runner.wait(timeout=60)
    deadline = time.monotonic() + 60
    while Path(f"/proc/{logger}").exists() and time.monotonic() < deadline:
        time.sleep(0.02)
    assert len(read_periods(tmp_path / "second.mcap")) == 250


def _environ_and_umask_worker(*args: object) -> None:
    """`run_worker`, the file it writes named after the worker's HIL_TEST_WORKER_ENV and umask."""
    from pmsm_hil.hil.runlog.worker import run_worker

    mask = os.umask(0)
    os.umask(mask)
    path = Path(str(args[4]))
    path.with_name(f"{os.environ.get('HIL_TEST_WORKER_ENV')}-{mask:o}").touch()
    run_worker(*args)


def test_a_forked_logger_has_the_runners_environment_and_umask_of_its_start(tmp_path: Path,
                                                                           monkeypatch: pytest.MonkeyPatch) -> None:
    """As a spawned one: not those the fork server had when it started (a runner that changed them since)."""
    from pmsm_hil.hil.runlog import logger as logger_module

    _write(tmp_path / "a.mcap", "forkserver")  # the fork server runs
    monkeypatch.setattr(logger_module, "run_worker", _environ_and_umask_worker)
    for method, value, mask in (("spawn", "one", 0o27), ("forkserver", "two", 0o77)):
        monkeypatch.setenv("HIL_TEST_WORKER_ENV", value)
        old = os.umask(mask)
        try:
            _write(tmp_path / f"{method}.mcap", method)
        finally:
            os.umask(old)
        assert (tmp_path / f"{value}-{mask:o}").exists(), sorted(p.name for p in tmp_path.iterdir())
