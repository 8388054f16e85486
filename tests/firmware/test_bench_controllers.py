"""`hil bench controllers`: parser wiring, timing figures, optional callgrind instruction counts."""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

import pytest

from pmsm_hil.app.cli import bench_controllers


def _parse(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    sub = parser.add_subparsers()
    bench_controllers.add_parser(sub)
    return parser.parse_args(["controllers", *argv])


def test_timing_without_valgrind(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "bench.json"
    args = _parse(["--steps", "300", "--repeats", "3", "--no-valgrind", "--json", str(out)])
    assert args.func(args) == 0
    payload = json.loads(out.read_text(encoding="utf-8"))
    names = [c["name"] for c in payload["controllers"]]
    assert {"mpcc", "dsvm-20", "fcs-mpc-1", "fcs-mpc-2", "dbcc-mpc", "foc"} <= set(names)
    mpcc = payload["controllers"][names.index("mpcc")]
    assert mpcc["name"] == "mpcc" and mpcc["controller_id"] == 1
    assert 0 < mpcc["ns_per_step"] < 1_000_000
    assert mpcc["ns_per_step_min_repeat"] <= mpcc["ns_per_step"]
    assert len(mpcc["split_ns"]) == 3 and mpcc["split_ns"][2] > 0
    assert mpcc["instructions_per_step"] is None
    text = capsys.readouterr().out
    assert "mpcc" in text and "55.83" in text  # paper's Table 4 beside ours


@pytest.mark.skipif(shutil.which("valgrind") is None, reason="valgrind not installed")
def test_instruction_counts_under_callgrind() -> None:
    counts, note = bench_controllers.count_instructions([1], 200)
    assert note == ""
    total, measure, reference, predict = counts[1]
    assert 100 < total < 20_000
    assert reference < measure < total and reference < predict < total
    assert measure + reference + predict == pytest.approx(total, rel=0.05)


def test_bad_step_count_is_a_usage_error(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit):
        _parse(["--steps", "0"])
    assert "whole number" in capsys.readouterr().err
