"""`hil bench memory` runs `hil run` in fresh interpreters and prints peak RSS, wall time and the verdicts."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from pmsm_hil.app.bench.memory import MemoryPoint, marginal_rates
from pmsm_hil.app.cli.main import main


def test_bench_memory_prints_figures(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "m.json"
    assert main(["bench", "memory", "--durations", "0.05,0.1", "--no-log", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    assert "host RSS MB" in text and "peak RSS of the longest run (0.1 s)" in text and "machine load" in text
    points = json.loads(out.read_text())["points"]
    assert [p["duration_s"] for p in points] == [0.05, 0.1]
    assert all(p["exit_code"] == 0 and p["periods"] > 0 and 20 < p["rss_host_mb"] < 2000 for p in points)


def test_bad_durations_name_the_option(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        main(["bench", "memory", "--durations", "10,-1"])
    assert "--durations" in capsys.readouterr().err


def test_marginal_rates_allow_a_fixed_start_up_cost() -> None:
    pts = [MemoryPoint(d, 2.0 + 0.5 * d, 1.0 + 0.25 * d, 0, 1.0, 1.0, 0) for d in (10.0, 60.0, 600.0)]
    assert marginal_rates(pts) == pytest.approx([0.5, 0.5])
    assert marginal_rates(pts, cpu=True) == pytest.approx([0.25, 0.25])
