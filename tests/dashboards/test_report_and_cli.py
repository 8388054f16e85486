"""`hil report` (self-contained HTML, values from metrics.json) and `hil run --rerun-save`."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.dashboards.report_data import load_run
from pmsm_hil.dashboards.report_figures import harmonic_spectrum
from tests.dashboards._rrd import rows_per_entity
from tests.dashboards.conftest import LiveRun


def test_report_is_self_contained_and_shows_the_metrics(live_run: LiveRun, second_run_dir: Path,
                                                       tmp_path: Path) -> None:
    out = tmp_path / "report.html"
    assert main(["report", str(live_run.run_dir), str(second_run_dir), "-o", str(out)]) == 0
    text = out.read_text(encoding="utf-8")
    assert not re.search(r"""(src|href)=["']?https?:""", text)  # no external resources
    assert text.count("<svg") == 5  # bars, waveforms, spectra + one whole-run plot per run
    assert text.count("class=\"whole-run\"") == 2 and "class=\"end\"" not in text
    for run_dir in (live_run.run_dir, second_run_dir):
        metrics = json.loads((run_dir / "metrics.json").read_text())
        assert f"{metrics['torque_ripple_rms_nm']:.3f}" in text
        assert f"{metrics['current_thd_pct']:.2f}" in text
    assert "fcs-mpc-1" in text and "mpcc" in text


def test_spectrum_thd_agrees_with_the_metrics(live_run: LiveRun) -> None:
    run = load_run(live_run.run_dir)
    orders, pct = harmonic_spectrum(run)
    assert orders[0] == 1 and pct[0] == pytest.approx(100.0)
    thd = float((pct[1:40] ** 2).sum() ** 0.5)  # orders 2..40
    assert thd == pytest.approx(run.metrics["current_thd_pct"], rel=0.1)


def test_report_rejects_a_directory_without_a_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", str(tmp_path), "-o", str(tmp_path / "r.html")]) == 2
    assert "needs metrics.json and run.mcap" in capsys.readouterr().err


def test_hil_run_rerun_save(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rrd = tmp_path / "run.rrd"
    code = main(["run", "--duration", "0.02", "--settle", "0.01", "--no-log", "--rerun-save", str(rrd)])
    assert code == 0
    assert "torque ripple RMS" in capsys.readouterr().out
    assert rows_per_entity(rrd)["/torque/actual"] == 300


def test_hil_run_rerun_save_bad_directory(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", "--duration", "0.02", "--no-log", "--rerun-save", str(tmp_path / "no" / "x.rrd")])
    assert code == 2
    err = capsys.readouterr().err
    assert "--rerun-save" in err and "Traceback" not in err
