"""`hil bench memory` runs `hil run` in fresh interpreters and prints peak RSS, wall time and the verdicts."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pmsm_hil.app.bench.memory import MemoryPoint, format_points, marginal_rates, realtime_growth
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


def test_realtime_mode_runs_paced_and_prints_the_rss_growth(tmp_path: Path,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "rt.json"
    assert main(["bench", "memory", "--mode", "realtime", "--durations", "0.2,0.4", "--no-log", "--json",
                 str(out)]) == 0
    text = capsys.readouterr().out
    assert "real time: RSS (host + logger) of the 0.4 s run vs the 0.2 s run" in text and "MB/min" in text
    assert "marginal wall time" not in text  # a paced run's wall time is its duration: no linearity verdict
    points = json.loads(out.read_text())["points"]
    assert all(p["exit_code"] == 0 and p["wall_s"] >= p["duration_s"] for p in points)


def test_realtime_growth_is_relative_and_per_minute() -> None:
    pts = [MemoryPoint(60.0, 60.0, 1.0, 0, 100.0, 50.0, 0), MemoryPoint(600.0, 600.0, 10.0, 0, 106.0, 57.5, 0)]
    growth = realtime_growth(pts)
    assert growth is not None
    assert growth[0] == pytest.approx(0.09) and growth[1] == pytest.approx(13.5 / 9.0)
    assert any("+9.0%" in line and line.endswith("— met") for line in format_points(pts, realtime=True))
