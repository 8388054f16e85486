"""Live dashboard → .rrd during a real run, read back with the SDK and `rerun rrd verify`; MCAP replay."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.dashboards import entities as ent
from tests.dashboards._rrd import rows_per_entity
from tests.dashboards.conftest import LiveRun

PERIODS = 700  # 20 ms settle + 50 ms window at 100 µs


def test_live_rrd_has_every_period_on_every_entity(live_run: LiveRun) -> None:
    assert live_run.result.outcome.completed_periods == PERIODS
    assert live_run.periods == PERIODS
    counts = rows_per_entity(live_run.rrd)
    for path in ent.PER_PERIOD:
        assert counts.get(path) == PERIODS, path
    assert counts[ent.EXEC_HIST] == 1  # one cumulative histogram per block (700 periods: one block)


def test_rrd_verifies_with_rerun_cli(live_run: LiveRun) -> None:
    exe = Path(sys.executable).with_name("rerun")
    rerun = str(exe) if exe.exists() else shutil.which("rerun")
    if rerun is None:
        pytest.skip("rerun CLI not on PATH")
    proc = subprocess.run([rerun, "rrd", "verify", str(live_run.rrd)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    assert "verified without error" in proc.stdout + proc.stderr


def test_rrd_values_match_the_period_records(live_run: LiveRun) -> None:
    from rerun.chunk import RrdReader

    periods = live_run.result.outcome.periods.all()
    reader = RrdReader(live_run.rrd)
    values = []
    for chunk in reader.stream(store=reader.recordings()[0]):
        if chunk.entity_path == ent.TORQUE and not chunk.is_static:
            batch = chunk.to_record_batch()
            col = next(c for c in batch.schema.names if c.endswith("scalars"))
            values.extend(np.concatenate(batch.column(col).to_pylist()).tolist())
    assert np.allclose(values, periods["torque"])


def test_replay_mcap_into_the_same_entities(live_run: LiveRun, tmp_path: Path,
                                           capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "replay.rrd"
    assert main(["replay", str(live_run.run_dir / "run.mcap"), "--rerun-save", str(out)]) == 0
    assert f"replayed {PERIODS} periods" in capsys.readouterr().out
    assert rows_per_entity(out) == rows_per_entity(live_run.rrd)


def test_replay_errors_are_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["replay", str(tmp_path / "missing.mcap"), "--rerun-save", str(tmp_path / "x.rrd")]) == 2
    assert "is not a file" in capsys.readouterr().err
    (tmp_path / "run.mcap").write_bytes(b"x")
    assert main(["replay", str(tmp_path / "run.mcap")]) == 2
    assert "neither an MCAP run log (bad magic) nor a CAN log" in capsys.readouterr().err
    (tmp_path / "run.mcap").write_bytes(b"\x89MCAP0\r\n")
    assert main(["replay", str(tmp_path / "run.mcap")]) == 2
    assert "--rerun-save" in capsys.readouterr().err
    assert main(["replay", str(tmp_path / "run.mcap"), "--rerun-save", str(tmp_path / "x.rrd")]) == 2
    err = capsys.readouterr().err
    assert "is cut or corrupt after 8 of 8 bytes" in err and "hil mcap-repair" in err
    assert len(err.strip().splitlines()) == 1
    (tmp_path / "empty.csv").write_bytes(b"")
    assert main(["replay", str(tmp_path / "empty.csv")]) == 2
    err = capsys.readouterr().err
    assert "CSV" in err and "is empty: not a CAN log" in err and len(err.strip().splitlines()) == 1
