"""`hil compare --report`: the report's runs log with the trace, the HTML is self-contained and names the
controllers; the selection (one point, first rotor angle, at most MAX_REPORT_RUNS) and tripped runs."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.app.compare import load_preset, run_preset
from pmsm_hil.app.compare.preset import Variant
from pmsm_hil.app.compare.report_runs import MAX_REPORT_RUNS, ReportSelection, dir_name, write_compare_report
from pmsm_hil.dashboards.errors import DashboardError
from pmsm_hil.dashboards.report_data import load_run
from pmsm_hil.hil.records import TRACE_DTYPE6
from pmsm_hil.hil.runlog.reader import read_trace
from tests.compare._presets import load_text, preset_file

TINY = ('name = "tiny"\nmotor = "niu2020-ipmsm"\nscenario = "steady"\ncontrollers = ["mpcc", "dsvm-20"]\n'
        'settle_s = 0.01\nduration_s = 0.02\nfigure = "bars"\n')


def _self_contained(text: str) -> bool:
    """No external resource: no http(s) src/href, no linked stylesheet or script file."""
    return not re.search(r"""(src|href)=["']?(https?:|//)""", text) and "<link" not in text \
        and "<script src" not in text


def test_cli_report_logs_the_runs_and_writes_the_page(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "out"
    rc = main(["compare", "--preset", str(preset_file(tmp_path, TINY, "tiny.toml")), "--out", str(out),
               "--quiet", "--report"])
    assert rc == 0
    assert "tiny.html" in capsys.readouterr().out
    text = (out / "tiny.html").read_text(encoding="utf-8")
    assert text.startswith("<!DOCTYPE html>") and _self_contained(text)
    assert text.count("<svg") == 3
    assert "mpcc · Ts = 100 µs" in text and "dsvm-20 · Ts = 100 µs" in text
    rows = json.loads((out / "tiny.json").read_text(encoding="utf-8"))["rows"]
    for row in rows:
        run_dir = Path(row["run_dir"])
        assert run_dir == out / "runs" / "tiny" / row["label"]
        run = load_run(run_dir)  # metrics.json + run.mcap, trace logged
        assert run.source == "trace (2 µs)"
        assert f"{run.metrics['torque_ripple_rms_nm']:.3f}" in text


def test_cli_report_file_and_no_logging_without_it(tmp_path: Path) -> None:
    preset = str(preset_file(tmp_path, TINY, "tiny.toml"))
    plain, with_file = tmp_path / "plain", tmp_path / "with_file"
    assert main(["compare", "--preset", preset, "--out", str(plain), "--quiet", "--controllers", "mpcc"]) == 0
    assert not (plain / "runs").exists() and not (plain / "tiny.html").exists()
    page = tmp_path / "pages" / "r.html"
    assert main(["compare", "--preset", preset, "--out", str(with_file), "--quiet", "--controllers", "mpcc",
                 "--report", str(page)]) == 0
    assert "mpcc" in page.read_text(encoding="utf-8") and not (with_file / "tiny.html").exists()
    assert (with_file / "runs" / "tiny" / "mpcc" / "run.mcap").is_file()


def test_tripped_runs_are_skipped_and_named(tmp_path: Path) -> None:
    preset = load_text(tmp_path, TINY.replace('["mpcc", "dsvm-20"]', '["mpcc"]'))
    selection = ReportSelection(preset, tmp_path / "runs")
    result = run_preset(preset, run_dir=selection)
    trip = dict(result.rows[0], label="foc", controller="foc", run_dir=str(tmp_path / "runs" / "foc"),
                end_reason="plant trip: overcurrent; inverter put in the safe state (zero vector)")
    result.rows.append(trip)  # a trip row as run_preset records it (the directory has no metrics.json)
    summary = write_compare_report(result, selection, tmp_path / "r.html")
    text = summary.path.read_text(encoding="utf-8")
    assert summary.shown == ["mpcc · Ts = 100 µs"] and summary.skipped[0][0] == "foc"
    assert "Skipped (no usable metrics window): foc: plant trip: overcurrent" in text
    assert text.count("<svg") == 3 and "foc · " not in text
    result.rows = [trip]
    with pytest.raises(DashboardError, match="no run of preset 'tiny' completed"):
        write_compare_report(result, selection, tmp_path / "none.html")


def test_selection_one_point_first_angle_capped(tmp_path: Path) -> None:
    variants = "".join(f'[[variants]]\nlabel = "v {k} (x)"\ncontroller = "mpcc"\n' for k in range(MAX_REPORT_RUNS + 2))
    preset = load_text(tmp_path, 'name = "s"\nmotor = "niu2020-ipmsm"\nscenario = "steady"\ncontrollers = []\n'
                                 'theta0_rad = [0.0, 1.3]\n[sweep]\nkey = "load_nm"\nvalues = [7.0, 1.0, 3.0]\n'
                                 + variants)
    sel = ReportSelection(preset, tmp_path)
    assert sel.point == {"load_nm": 7.0}
    specs = preset.specs()
    assert sel(specs[0], {"load_nm": 1.0}, 0.0, "main") is None
    assert sel(specs[0], {"load_nm": 7.0}, 1.3, "main") is None
    dirs = [sel(s, {"load_nm": 7.0}, 0.0, "main") for s in specs]
    assert dirs[0] == tmp_path / "v-0-x" and dirs[MAX_REPORT_RUNS - 1] is not None
    assert dirs[MAX_REPORT_RUNS:] == [None, None] and sel.left_out == ["v 8 (x)", "v 9 (x)"]
    assert sel(specs[0], {"load_nm": 7.0}, 0.0, "main") == dirs[0]  # same run, same directory


def test_selection_names_equal_fav_and_dedupes(tmp_path: Path) -> None:
    preset = load_preset("niu2020-steady")
    sel = ReportSelection(preset, tmp_path)
    assert sel.point == {}
    a = sel(Variant("a/b", "mpcc"), {}, 0.0, "main")
    b = sel(Variant("a b", "mpcc"), {}, 0.0, "main")
    eq = sel(Variant("mpcc", "mpcc"), {}, 0.0, "equal_fav")
    assert (a, b, eq) == (tmp_path / "a-b", tmp_path / "a-b-2", tmp_path / "mpcc-equal-fav")
    assert sel(Variant("mpcc", "mpcc"), {}, 0.0, "equal_fav") == eq  # every equal-f_av iteration overwrites
    assert dir_name("../..") == "run" and dir_name("t_thr=8us min_tr") == "t_thr=8us-min_tr"


TINY6 = ('name = "tiny6"\nmotor = "zhang2021-dtpmsm"\nscenario = "steady"\ncontrollers = ["mptc2"]\n'
         'settle_s = 0.01\nduration_s = 0.02\nfigure = "bars"\nload_nm = 40.0\n')


def test_cli_report_of_a_six_phase_preset(tmp_path: Path) -> None:
    """The report logs the six-phase trace (both current sets and x-y) and renders it (exit 2 before the
    machine descriptor: the logger took only the three-phase trace)."""
    out = tmp_path / "out"
    assert main(["compare", "--preset", str(preset_file(tmp_path, TINY6, "tiny6.toml")), "--out", str(out),
                 "--quiet", "--report"]) == 0
    run = load_run(out / "runs" / "tiny6" / "mptc2")
    assert run.source == "trace (2 µs)"
    assert read_trace(out / "runs" / "tiny6" / "mptc2" / "run.mcap").dtype.names == TRACE_DTYPE6.names
    assert "mptc2" in (out / "tiny6.html").read_text(encoding="utf-8")
