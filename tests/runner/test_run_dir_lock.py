"""One run at a time in a run directory: a second run into the same --out is refused with exit 2."""

from __future__ import annotations

import fcntl
import json
import os
import signal
import time
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.runlog.reader import read_periods
from pmsm_hil.hil.runner.run_dir_lock import LOCK_NAME, RunDirLockedError, run_dir_lock
from tests.runner.hil_zygote import start_hil

SHORT = ["--duration", "0.05", "--settle", "0"]


def test_a_second_run_into_a_locked_out_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "r"
    out.mkdir()
    fd = os.open(out / LOCK_NAME, os.O_RDWR | os.O_CREAT)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)  # another open file: conflicts as another process would
        os.write(fd, b"4242\n")
        assert main(["run", "--out", str(out), *SHORT]) == 2
        assert main(["run", "--out", str(out), "--overwrite", *SHORT]) == 2
    finally:
        os.close(fd)
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(line.startswith(f"hil: error: --out {out}: another run (pid 4242)") for line in err)
    assert sorted(p.name for p in out.iterdir()) == [LOCK_NAME]  # nothing written, nothing removed
    assert main(["run", "--out", str(out), *SHORT]) == 0  # the lock is released with the process's file
    assert json.loads((out / "metrics.json").read_text())["total_periods"] == read_periods(out / "run.mcap").shape[0]


def test_concurrent_runs_into_one_out(tmp_path: Path) -> None:
    """Three `hil run` processes into one --out: one writes it, the others exit 2 without touching it. The first
    is a real-time run (1 ms period: 5 s of wall time for 5000 periods at a few percent of a CPU; a lockstep run
    that long would be as long in CPU time), stopped (SIGSTOP) once it writes its log so that it still holds the
    directory however long the others take to start on a busy machine, and continued once they have ended."""
    out = tmp_path / "r"
    cmd = ["run", "--out", str(out), "--overwrite", "--duration", "5", "--settle", "0"]
    # forked with their imports made (tests/runner/hil_zygote.py): processes of their own, as the lock needs
    first = start_hil([*cmd, "--mode", "realtime", "--ts", "1e-3"], tmp_path / "first.err", session=True)
    try:
        deadline = time.monotonic() + 60
        while not (out / "run.mcap").exists() and time.monotonic() < deadline:
            time.sleep(0.02)
        os.killpg(first.pid, signal.SIGSTOP)  # the run and its logger
        assert first.poll() is None, "the first run ended before the others started"
        procs = [start_hil(cmd, tmp_path / f"other{k}.err") for k in range(2)]
        others = [(p.wait(timeout=120), (tmp_path / f"other{k}.err").read_text()) for k, p in enumerate(procs)]
    finally:
        os.killpg(first.pid, signal.SIGCONT)
    first.wait(timeout=120)
    assert first.returncode == 0, (tmp_path / "first.err").read_text()
    for rc, err in others:
        assert rc == 2 and err.startswith(f"hil: error: --out {out}: another run (pid {first.pid})"), err
        assert "Traceback" not in err
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["total_periods"] == read_periods(out / "run.mcap").shape[0] == 5_000


def test_the_lock_nests_in_one_process(tmp_path: Path) -> None:
    with run_dir_lock(tmp_path / "r"), run_dir_lock(tmp_path / "r" / ".." / "r"):  # the CLI, then the runner
        pass
    with run_dir_lock(tmp_path / "r"):
        fd = os.open(tmp_path / "r" / LOCK_NAME, os.O_RDWR)
        try:
            with pytest.raises(BlockingIOError):
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        finally:
            os.close(fd)
    (tmp_path / "f").write_text("x")
    with pytest.raises(Exception, match="exists and is not a directory"), run_dir_lock(tmp_path / "f"):
        pass
    assert issubclass(RunDirLockedError, Exception)
