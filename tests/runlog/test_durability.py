"""Kills: the loop process (logger finalises on EOF), both processes (repair path), the logger alone."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.hil.runlog import LoggerDiedError, RunLogger, read_periods, repair_mcap
from pmsm_hil.hil.runlog.reader import MAGIC
from tests.runlog._blocks import period_block

CHILD = Path(__file__).with_name("_loop_child.py")
REPO = Path(__file__).resolve().parents[2]


def _progress(path: Path) -> tuple[int, list[tuple[float, int]]]:
    lines = path.read_text().splitlines()
    logger_pid = int(lines[0].split()[1])
    rows = [(float(a), int(b)) for a, b in (line.split() for line in lines[1:] if len(line.split()) == 2)]
    return logger_pid, rows


def _run_and_kill(
    tmp_path: Path, flush_s: float, run_s: float, kill_logger_first: bool = False, flushes: int = 0,
    on_disk: list[int] | None = None
) -> tuple[Path, int, float, list[tuple[float, int]]]:
    """Run the loop child for `run_s` of submitting, and (with `flushes`) until the periods readable from the live
    file changed `flushes` times (the logger's own progress: load-independent; the counts seen go to `on_disk`),
    then SIGKILL it (and its logger first); returns the file, the logger's pid, the kill's monotonic time and the
    child's progress rows."""
    out, prog = tmp_path / "run.mcap", tmp_path / "progress.txt"
    child = subprocess.Popen([sys.executable, str(CHILD), str(out), str(prog), str(flush_s)], cwd=REPO)
    try:
        deadline = time.monotonic() + 60.0
        started = None
        seen = on_disk if on_disk is not None else []
        while time.monotonic() < deadline:
            if prog.exists() and len(prog.read_text().splitlines()) > 1:
                started = started or time.monotonic()
                if flushes and out.exists() and out.stat().st_size >= len(MAGIC):  # its header written
                    seen.append(read_periods(out).shape[0])
                if time.monotonic() - started >= run_s and len(set(seen) - {0}) >= flushes:
                    break
            if child.poll() is not None:
                pytest.fail(f"loop child exited early with code {child.returncode}")
            time.sleep(0.05)
        kill_time = time.monotonic()
        if kill_logger_first:  # both die: the logger cannot finalise the file
            os.kill(_progress(prog)[0], signal.SIGKILL)
        child.send_signal(signal.SIGKILL)
        child.wait(10)
    finally:
        if child.poll() is None:
            child.kill()
    logger_pid, rows = _progress(prog)
    return out, logger_pid, kill_time, rows


def _wait_gone(pid: int, timeout_s: float) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
        except (FileNotFoundError, ProcessLookupError):
            return True
        if state == "Z":  # exited, not yet reaped by its new parent
            return True
        time.sleep(0.05)
    return False


def test_sigkill_of_loop_logger_finalises_file(tmp_path: Path) -> None:
    # 1.2 s of submitting: past the first flush (1 s), so the logger finalises a file it had already written to;
    # a longer run only adds blocks to the same checks
    out, logger_pid, _kill_time, rows = _run_and_kill(tmp_path, flush_s=1.0, run_s=1.2)
    assert _wait_gone(logger_pid, 30.0), "logger did not exit after the loop was killed"
    assert out.read_bytes()[-len(MAGIC) :] == MAGIC  # footer magic: finalised by the logger
    periods = read_periods(out)
    submitted = rows[-1][1] + 1  # every completed submit reached the logger before the kill
    assert periods.shape[0] >= submitted
    np.testing.assert_array_equal(periods["seq"], np.arange(periods.shape[0]))
    np.testing.assert_array_equal(periods[:submitted]["i_a"], _expected(submitted)["i_a"])


def _expected(n: int) -> np.ndarray:
    return np.concatenate([period_block(k, 200) for k in range(0, n, 200)])[:n]


def _assert_repairs(out: Path, repaired: Path, periods: np.ndarray) -> None:
    """The cut file `out` (its valid prefix: `periods`) repairs into `repaired`, finalised, with the same periods."""
    report = repair_mcap(out, repaired)
    assert not report.source_complete and report.chunks >= 2
    assert report.messages_per_topic["/periods"] == periods.shape[0]
    assert repaired.read_bytes()[-len(MAGIC) :] == MAGIC
    np.testing.assert_array_equal(read_periods(repaired)["seq"], periods["seq"])


def test_sigkill_of_loop_and_logger_keeps_what_the_logger_had_written(tmp_path: Path) -> None:
    """Both killed (no footer): every period the file held before the kill is still read, and the repair
    finalises a file with them; the kill comes once the logger has flushed at least twice, whatever the load."""
    on_disk: list[int] = []
    out, logger_pid, _kill_time, _rows = _run_and_kill(tmp_path, flush_s=0.5, run_s=1.0, kill_logger_first=True,
                                                       flushes=2, on_disk=on_disk)
    assert _wait_gone(logger_pid, 10.0)
    assert out.read_bytes()[-len(MAGIC) :] != MAGIC  # cut: no footer
    periods = read_periods(out)  # tolerant reader (valid prefix)
    assert len(set(on_disk) - {0}) >= 2 and periods.shape[0] >= max(on_disk)
    np.testing.assert_array_equal(periods["seq"], np.arange(periods.shape[0]))
    _assert_repairs(out, tmp_path / "repaired.mcap", periods)


@pytest.mark.timing  # the logger must have written a block within 1 s of its submit: beside a burner it falls behind
def test_sigkill_of_loop_and_logger_keeps_all_but_last_second(tmp_path: Path) -> None:
    out, logger_pid, kill_time, rows = _run_and_kill(tmp_path, flush_s=0.5, run_s=2.5, kill_logger_first=True)
    assert _wait_gone(logger_pid, 10.0)
    assert out.read_bytes()[-len(MAGIC) :] != MAGIC  # cut: no footer
    older = [seq for t, seq in rows if t <= kill_time - 1.0]
    assert older, "no block was submitted more than 1 s before the kill"
    periods = read_periods(out)  # tolerant reader (valid prefix)
    assert periods.shape[0] >= older[-1] + 1
    _assert_repairs(out, tmp_path / "repaired.mcap", periods)


def test_logger_death_is_reported_on_next_submit(tmp_path: Path) -> None:
    lg = RunLogger(tmp_path / "run.mcap", metadata={})
    lg.submit_periods(period_block(0, 100))
    assert lg.pid is not None
    os.kill(lg.pid, signal.SIGKILL)
    start = time.monotonic()
    with pytest.raises(LoggerDiedError, match=r"died \(exit code -9\)"):
        for k in range(1000):
            lg.submit_periods(period_block(k, 100))
            time.sleep(0.01)
    assert time.monotonic() - start < 10.0
    with pytest.raises(LoggerDiedError):
        lg.close()
    lg.close()  # idempotent after the error


def test_sigterm_to_logger_finalises(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    lg = RunLogger(path, metadata={})
    lg.submit_periods(period_block(0, 300))
    time.sleep(0.3)
    assert lg.pid is not None
    os.kill(lg.pid, signal.SIGTERM)
    assert _wait_gone_child(lg, 10.0)
    assert path.read_bytes()[-len(MAGIC) :] == MAGIC
    assert read_periods(path).shape[0] == 300
    lg.close()
    assert lg.final_stats is not None and lg.final_stats["reason"] == "sigterm"


def test_a_sigterm_keeps_the_blocks_a_runner_without_cpu_sends_late(tmp_path: Path) -> None:
    """A group SIGTERM on a busy machine: the runner (this process) gets to its last blocks only after more than
    SIGTERM_IDLE_S, runnable all the while (a spin stands for a runner waiting for a CPU). The logger counts idle
    time only while the runner sleeps, so every period is in the file (it ended after 1 s of wall time before:
    27 000 of 32 791 periods in test_interrupt_log at load 12-19)."""
    from pmsm_hil.hil.runlog.runner_watch import SIGTERM_IDLE_S

    path = tmp_path / "run.mcap"
    lg = RunLogger(path, metadata={})
    lg.submit_periods(period_block(0, 300))
    assert lg.pid is not None
    os.kill(lg.pid, signal.SIGTERM)
    t0 = time.monotonic()
    while time.monotonic() - t0 < 1.5 * SIGTERM_IDLE_S:
        pass  # runnable, no notice
    lg.submit_periods(period_block(300, 300))
    lg.close()
    assert read_periods(path)["seq"].tolist() == list(range(600))
    assert lg.final_stats is not None and lg.final_stats["reason"] == "sigterm"


def _wait_gone_child(lg: RunLogger, timeout_s: float) -> bool:
    proc = lg._proc
    proc.join(timeout_s)
    return not proc.is_alive()
