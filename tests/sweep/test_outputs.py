"""What a sweep writes: rows with configuration, run id, end code and reason and every metric (JSON,
Parquet, or CSV without pyarrow), one MCAP per run in the store, a summary table and an HTML page; a run
that fails is a row, not the end of the sweep."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.app.sweep import store as store_module
from tests.sweep._plans import SHORT, results

#: 4 runs: two complete, two end as DUT contract violations (the link goes silent at 10 ms)
PLAN = ["--grid", "fault=drop=0;silence=0.01:0.05", "--grid", "load=3,7", *SHORT, "--workers", "0", "--quiet"]


@pytest.fixture(scope="module")
def swept(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("sweep")
    assert main(["sweep", *PLAN, "--out", str(out), "--mcap", "--store", str(out / "store")]) == 0
    return out


def test_rows_hold_configuration_end_and_metrics(swept: Path) -> None:
    rows = list(results(swept).values())
    assert len(rows) == 4
    ok = [r for r in rows if r["fault"] == "drop=0"]
    bad = [r for r in rows if r["fault"] != "drop=0"]
    assert sorted(r["load"] for r in ok) == [3.0, 7.0]
    for r in ok:
        assert r["end_code"] == 0 and r["end_reason"] == "completed"
        assert r["torque_ripple_rms_nm"] > 0 and r["controller"] == "mpcc" and r["seed"] == 0
        assert isinstance(r["exec_time_us.median"], float) and "link.frames_tx" in r
        assert json.loads(r["config"]) == {"fault": "drop=0", "load": str(int(r["load"]))}
        assert hashlib.sha256(r["run_config"].encode()).hexdigest()[:16] == r["run_id"]
        assert json.loads(r["run_config"])["scenario"]["duration_s"] == 0.03
    for r in bad:  # a failed run is a row with its end code and reason
        assert r["end_code"] == 4 and "DUT contract violation" in r["end_reason"]
        assert r["torque_ripple_rms_nm"] is None


def test_parquet_matches_json(swept: Path) -> None:
    pq = pytest.importorskip("pyarrow.parquet")
    table = pq.read_table(swept / "results.parquet").to_pylist()
    by_id = results(swept)
    assert {r["run_id"] for r in table} == set(by_id)
    for r in table:
        assert r["end_code"] == by_id[r["run_id"]]["end_code"]
        assert r["torque_ripple_rms_nm"] == by_id[r["run_id"]]["torque_ripple_rms_nm"]


def test_one_mcap_per_run_in_the_store(swept: Path) -> None:
    for rid, row in results(swept).items():
        assert row["mcap"] == str((swept / "store" / rid / "run.mcap").resolve())
        assert Path(row["mcap"]).stat().st_size > 0 and (swept / "store" / rid / "metrics.json").is_file()


def test_report_page(swept: Path) -> None:
    page = (swept / "report.html").read_text(encoding="utf-8")
    assert "<svg" in page and 'id="vs-load"' in page and "Runs that did not complete" in page
    assert "DUT contract violation" in page


def test_summary_printed_and_failures_counted(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                              monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(store_module, "has_parquet", lambda: False)
    assert main(["sweep", *PLAN, "--out", str(tmp_path)]) == 0
    captured = capsys.readouterr()
    lines = captured.out.splitlines()
    assert lines[0].split()[:4] == ["fault", "load", "runs", "failed"]
    assert any(line.startswith("silence=0.01:0.05") and line.split()[3] == "1" for line in lines)
    assert "hil: 2 of 4 runs did not complete" in captured.err
    assert (tmp_path / "results.csv").is_file() and not (tmp_path / "results.parquet").exists()
    header = (tmp_path / "results.csv").read_text(encoding="utf-8").splitlines()[0].split(",")
    assert header[:4] == ["run_id", "end_code", "end_reason", "fault"]
    # the same command again: every run done before, nothing runs, the same rows
    assert main(["sweep", *PLAN, "--out", str(tmp_path)]) == 0
    assert len(results(tmp_path)) == 4
