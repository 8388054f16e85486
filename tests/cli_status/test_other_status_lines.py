"""The status line of `hil bench`, `hil fw build` and `hil replay` on a terminal (a pty): each names its phase and
ends `done`, the command's own output printed above it; nothing of it when stdout is not a terminal."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from tests.cli_status.pty_run import run_on_pty

BENCH = ["bench", "plant", "--periods", "500", "--repeats", "1", "--accuracy-periods", "100", "--no-gem"]


def test_a_bench_draws_its_phase_and_prints_its_figures_above_it() -> None:
    out = run_on_pty(BENCH)
    assert out.code == 0, out.text
    text = out.text
    assert out.first("hil bench plant: starting") is not None
    assert "hil bench plant: measuring" in text and "hil bench plant: done" in text
    # the bench's own lines are whole lines above the status line, none cut by it
    lines = [ln.split("\r")[-1] for ln in text.split("\r\n") if ln.strip()]
    printed = [ln for ln in lines if "hil bench plant:" not in ln]
    assert printed and all("[" not in ln or "]" in ln for ln in printed), printed


def test_a_bench_without_a_terminal_prints_only_its_figures(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(BENCH) == 0
    captured = capsys.readouterr()
    assert captured.out.strip() and "hil bench plant:" not in captured.out + captured.err
    assert "\r" not in captured.out + captured.err


@pytest.mark.skipif(shutil.which("cmake") is None, reason="cmake not installed")
def test_fw_build_draws_its_steps(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = run_on_pty(["fw", "build", "--no-cache", "-o", str(tmp_path / "fw.so")], timeout_s=600.0)
    assert out.code == 0, out.text
    text = out.text
    for phase in ("starting", "configuring", "building", "done"):
        assert f"hil fw build: {phase}" in text, text
    assert out.first("hil fw build: configuring") < out.first("hil fw build: done")  # type: ignore[operator]
    assert re.search(r"built \S+fw\.so \(host", text)
    assert main(["fw", "build", "-o", str(tmp_path / "fw2.so")]) == 0
    captured = capsys.readouterr()
    assert "hil fw build:" not in captured.out + captured.err and "built " in captured.out


def test_replay_draws_the_periods_it_sent(tmp_path: Path) -> None:
    assert main(["run", "--settle", "0.02", "--duration", "0.03", "--out", str(tmp_path / "run")]) == 0
    out = run_on_pty(["replay", str(tmp_path / "run" / "run.mcap"), "--rerun-save", str(tmp_path / "r.rrd")])
    assert out.code == 0, out.text
    text = out.text
    assert "hil replay: reading run.mcap" in text and "hil replay: done" in text
    assert "500/500 periods" in text and "replayed 500 periods" in text
    assert (tmp_path / "r.rrd").is_file()
