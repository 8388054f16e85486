"""Resumable and observable: a real SIGINT to a running `hil sweep` keeps the finished runs, the same
command then runs only the rest; the journal tolerates a line cut by a crash; a lost worker is a row and
the pool goes on."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from pmsm_hil.app.sweep.engines import LocalEngine
from pmsm_hil.app.sweep.store import JOURNAL, ResultsStore
from tests.sweep._plans import SHORT, results

PLAN = ["--grid", "controller=mpcc,dsvm-20", "--grid", "load=3,7", "--repeat", "2", *SHORT]


def _journal_rows(out: Path) -> int:
    try:
        return sum(1 for line in (out / JOURNAL).read_text(encoding="utf-8").splitlines() if line.endswith("}"))
    except FileNotFoundError:
        return 0


def test_sigint_keeps_finished_runs_and_the_rerun_skips_them(tmp_path: Path) -> None:
    out = tmp_path / "sweep"
    cmd = [sys.executable, "-m", "pmsm_hil.app.cli.main", "sweep", *PLAN, "--workers", "1", "--out", str(out)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while _journal_rows(out) < 2 and proc.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted" in err and "the same command resumes the sweep" in err
    first = results(out)  # written at the interruption: the runs that finished
    assert 2 <= len(first) < 8
    assert all(row["end_code"] == 0 for row in first.values())

    again = subprocess.run(cmd, capture_output=True, text=True, timeout=180)
    assert again.returncode == 0, again.stderr
    assert f"8/8 runs ({len(first)} done before)" in again.stderr
    final = results(out)
    assert len(final) == 8 and all(row["end_code"] == 0 for row in final.values())
    for rid, row in first.items():  # not run again: the same row, from the first process
        assert final[rid]["pid"] == row["pid"] and final[rid]["run_wall_s"] == row["run_wall_s"]
    assert _journal_rows(out) == 8  # every run once


def test_journal_ignores_a_cut_line_and_interrupted_runs(tmp_path: Path) -> None:
    (tmp_path / JOURNAL).write_text(
        json.dumps({"run_id": "a", "end_code": 0}) + "\n" + json.dumps({"run_id": "b", "end_code": 130}) + "\n"
        + json.dumps({"run_id": "c", "end_code": 1, "end_reason": "worker lost: died"}) + "\n"
        + '{"run_id": "d", "end_co', encoding="utf-8")
    store = ResultsStore(tmp_path)
    assert store.done_ids() == {"a"}  # b interrupted and c lost run again; d was cut
    store.add({"run_id": "d", "end_code": 3, "end_reason": "plant trip"})
    assert ResultsStore(tmp_path).done_ids() == {"a", "d"}
    assert ResultsStore(tmp_path, overwrite=True).done_ids() == set()


def crash_on_two(x: int) -> int:
    """A task whose worker dies on 2 (module-level: sent by reference)."""
    if x == 2:
        os._exit(3)
    return x * 10


def test_a_dead_worker_is_reported_and_the_pool_goes_on() -> None:
    with LocalEngine(1) as engine:
        got = {i: (res, err) for i, res, err in engine.map_unordered(crash_on_two, [0, 1, 2, 3, 4])}
    assert [got[i][0] for i in (0, 1, 3, 4)] == [0, 10, 30, 40]
    assert got[2][0] is None and "worker process died" in str(got[2][1])
