"""Single-run report: whole-run plots (min/max-decimated, bounded points per trace) and runs that ended early
(the end box with reason, code, period and time, the end marked on the plots, no empty chart)."""

from __future__ import annotations

import html
import json
import re
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.dashboards.decimate import minmax_decimate
from pmsm_hil.dashboards.report_data import load_run
from pmsm_hil.dashboards.report_whole_run import MAX_POINTS_PER_TRACE
from pmsm_hil.hil.runlog import read_periods

_SHORT = ["--duration", "0.05", "--settle", "0.02"]


def _run(out: Path, *args: str) -> int:
    return main(["run", "--out", str(out), *args])


def _report(run_dir: Path, out: Path) -> str:
    assert main(["report", str(run_dir), "-o", str(out)]) == 0
    return out.read_text(encoding="utf-8")


def _points(path_d: str) -> int:
    """Vertices of an SVG path (matplotlib writes M/L commands, one coordinate pair each)."""
    return len(re.findall(r"[ML]\s*-?[\d.]+\s+-?[\d.]+", path_d))


def _lines(text: str, prefix: str) -> dict[str, int]:
    """Points drawn per line whose SVG id starts with `prefix` (the gids of `report_figures.whole_run`)."""
    found = re.findall(r'<g id="(' + re.escape(prefix) + r'[^"]*)">\s*<path d="([^"]*)"', text)
    return {gid: _points(d) for gid, d in found}


def _metrics(run_dir: Path) -> dict[str, object]:
    return dict(json.loads((run_dir / "metrics.json").read_text()))


# --- decimation ---------------------------------------------------------------------------------------------

def test_minmax_decimation_is_bounded_keeps_peaks_and_time_order() -> None:
    rng = np.random.default_rng(1)
    n = 123_457
    t = np.arange(n) * 1e-4
    y = rng.normal(size=n)
    y[7777], y[98_765] = 50.0, -60.0  # one-sample spikes
    td, yd = minmax_decimate(t, y, 2000)
    assert 1000 < len(td) <= 2000
    assert yd.max() == 50.0 and yd.min() == -60.0
    assert np.all(np.diff(td) > 0)
    assert set(yd) <= set(y)  # samples, not averages


def test_minmax_decimation_short_series_and_nan() -> None:
    t = np.arange(10.0)
    assert minmax_decimate(t, t * 2, 10)[1].tolist() == (t * 2).tolist()
    y = np.full(5000, np.nan)
    y[:100] = np.arange(100.0)
    td, yd = minmax_decimate(np.arange(5000.0), y, 100)
    assert len(td) <= 100 and np.nanmax(yd) == 99.0 and np.nanmin(yd) == 0.0
    with pytest.raises(ValueError, match="max_points"):
        minmax_decimate(t, t, 1)


# --- a run that tripped before its metrics window ------------------------------------------------------------

@pytest.fixture(scope="module")
def tripped(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("trip") / "run"
    assert _run(out, "--controller", "off", "--set", "i_trip=3", *_SHORT) == 3
    return out


def test_tripped_run_report_says_where_and_why_and_draws_no_empty_chart(tripped: Path, tmp_path: Path) -> None:
    metrics = _metrics(tripped)
    assert metrics["end_code"] == 3 and metrics["periods"] == 0
    reason = str(metrics["end_reason"])
    assert reason.startswith("plant trip: overcurrent")
    text = _report(tripped, tmp_path / "r.html")
    box = re.search(r'<div class="end" id="end-0">(.*?)</div>', text, re.S)
    assert box is not None
    end_period = metrics["end_period"]
    assert isinstance(end_period, int)
    t_end = float(read_periods(tripped / "run.mcap")["t"][end_period])
    for needle in (html.escape(reason), "end_code 3 (safety stop)", f"end_period {end_period}",
                   f"at period {end_period} (t = {t_end * 1e3:.3f} ms)"):
        assert needle in box.group(1)
    # the whole-run plot is there, every trace drawn, the end marked; no window chart at all
    assert 'id="whole-run-0"' in text
    lines = _lines(text, "whole-0-")
    traces = {k: v for k, v in lines.items() if not k.endswith("-end")}
    assert len(traces) == 10  # speed 2, torque 3, phase currents 3, dq 2 (three phases: no second set)
    drawn = {f"whole-0-{k}-{j}": int(np.isfinite(tr.y).sum())
             for k, panel in enumerate(load_run(tripped).whole.panels) for j, tr in enumerate(panel.traces)}
    assert traces == drawn  # every finite sample of every logged period
    assert max(drawn.values()) == end_period + 1
    assert sum(k.endswith("-end") for k in lines) == 4  # the end line on each panel
    for chart in ('id="bars"', 'id="waveforms"', 'id="spectra"'):
        assert chart not in text
    assert text.count("<svg") == 1
    assert "before its metrics window began" in text


# --- a watchdog inside the metrics window --------------------------------------------------------------------

@pytest.fixture(scope="module")
def watchdog(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("watchdog") / "run"
    assert _run(out, "--fault", "silence=0.03:0.06", "--tolerate", "100", "--log-trace", *_SHORT) == 3
    return out


def test_watchdog_run_keeps_its_partial_window_without_empty_charts(watchdog: Path, tmp_path: Path) -> None:
    metrics = _metrics(watchdog)
    assert str(metrics["end_reason"]).startswith("watchdog")
    assert metrics["current_thd_pct"] is None and isinstance(metrics["periods"], int) and metrics["periods"] > 0
    text = _report(watchdog, tmp_path / "r.html")
    assert html.escape(str(metrics["end_reason"])) in text
    assert f"end_period {metrics['end_period']}" in text
    assert any(k.endswith("-end") for k in _lines(text, "whole-0-"))
    assert 'id="bars"' in text and 'id="waveforms"' in text
    assert 'id="spectra"' not in text  # no run has a spectrum: a sentence instead
    assert "No spectrum for" in text and "shorter than one electrical period" in text
    assert "No value in the metrics window for: current THD" in text
    bars = re.search(r'<figure id="bars">(.*?)</figure>', text, re.S)
    assert bars is not None and "current THD" not in bars.group(1)  # its empty chart is left out


# --- a long run ----------------------------------------------------------------------------------------------

def test_long_run_plot_is_decimated_to_the_bound_and_keeps_peaks(tmp_path: Path) -> None:
    run_dir = tmp_path / "long"
    # 4000 periods of 100 µs: twice the bound, so every trace is decimated (a bucket holds 4 periods)
    assert _run(run_dir, "--duration", "0.3", "--settle", "0.1") == 0
    text = _report(run_dir, tmp_path / "r.html")
    n = len(read_periods(run_dir / "run.mcap"))
    assert n == 4000 and n >= 2 * MAX_POINTS_PER_TRACE
    assert f"{n} periods, decimated: min and max of {MAX_POINTS_PER_TRACE // 2} buckets" in text
    lines = _lines(text, "whole-0-")
    assert len(lines) == 10
    assert all(0 < v <= MAX_POINTS_PER_TRACE for v in lines.values()), lines
    assert 'class="end"' not in text  # a completed run has no end box
    run = load_run(run_dir)
    periods = read_periods(run_dir / "run.mcap")
    torque = run.whole.panels[1].traces[0]
    assert torque.y.max() == periods["torque"].max() and torque.y.min() == periods["torque"].min()


def test_six_phase_run_plots_its_second_set(tmp_path: Path) -> None:
    run_dir = tmp_path / "six"
    assert _run(run_dir, "--motor", "zhang2021-dtpmsm", "--controller", "mptc2", "--duration", "0.01",
                "--settle", "0.01") == 0
    panels = [p.title for p in load_run(run_dir).whole.panels]
    assert panels == ["speed", "torque", "phase currents", "phase currents, second set", "dq currents"]
    assert len(_lines(_report(run_dir, tmp_path / "r.html"), "whole-0-3-")) == 3  # i_u, i_v, i_w


def test_bad_end_period_is_a_one_line_error(tripped: Path, tmp_path: Path,
                                            capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "run.mcap").write_bytes((tripped / "run.mcap").read_bytes())
    metrics = _metrics(tripped)
    metrics["end_period"] = "late"
    (bad / "metrics.json").write_text(json.dumps(metrics))
    assert main(["report", str(bad), "-o", str(tmp_path / "r.html")]) == 2
    err = capsys.readouterr().err
    assert "'end_period' must be a whole number" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1


def test_two_run_report_with_a_tripped_run(tripped: Path, watchdog: Path, second_run_dir: Path,
                                           tmp_path: Path) -> None:
    out = tmp_path / "r.html"
    assert main(["report", str(second_run_dir), str(tripped), str(watchdog), "-o", str(out)]) == 0
    text = out.read_text(encoding="utf-8")
    assert 'id="end-1"' in text and 'id="end-2"' in text and 'id="end-0"' not in text
    assert text.count('class="whole-run"') == 3
    assert "Not in the window charts: off · run ended at period" in text
    for chart in ('id="bars"', 'id="waveforms"', 'id="spectra"'):
        assert chart in text  # the completed run's (and the partial window's) charts
    assert "No spectrum for mpcc · run" in text  # the watchdog run's window is too short for one


def _no_period_run(run_dir: Path, end_code: int) -> None:
    """A run directory whose log holds the metadata but no period (as after an interrupt before period 0)."""
    from mcap.writer import Writer

    run_dir.mkdir()
    with open(run_dir / "run.mcap", "wb") as f:
        w = Writer(f)
        w.start()
        w.add_metadata("/run/metadata", {"controller": "mpcc", "ts_s": "0.0001"})
        w.finish()
    reason = "completed" if end_code == 0 else "interrupted (SIGINT)"
    (run_dir / "metrics.json").write_text(json.dumps({"periods": 0, "end_reason": reason, "end_code": end_code,
                                                      "end_period": -1}))


def test_run_without_periods(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _no_period_run(tmp_path / "early", 130)
    text = _report(tmp_path / "early", tmp_path / "r.html")
    assert "ended early</b> before the first period: interrupted (SIGINT)" in text
    assert "end_code 130 (interrupted)" in text
    assert "no period was logged" in text and "<svg" not in text
    _no_period_run(tmp_path / "done", 0)  # completed yet empty: inconsistent, refused
    assert main(["report", str(tmp_path / "done"), "-o", str(tmp_path / "d.html")]) == 2
    assert "holds no periods" in capsys.readouterr().err


@pytest.mark.parametrize(("content", "needle"), [
    ("[1, 2]", "must hold a JSON object"),
    ('{"end_code": 3, "end_period": 5, "periods": -1}', "'periods' must be a whole number ≥ 0"),
    ('{"end_code": "3", "end_period": 5}', "'end_code' must be a whole number"),
    ('{"end_code": 3, "end_period": 5, "end_reason": 7}', "'end_reason' must be a string"),
])
def test_malformed_metrics_are_one_line_errors(tripped: Path, tmp_path: Path, content: str, needle: str,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "run.mcap").write_bytes((tripped / "run.mcap").read_bytes())
    (bad / "metrics.json").write_text(content)
    assert main(["report", str(bad), "-o", str(tmp_path / "r.html")]) == 2
    err = capsys.readouterr().err
    assert needle in err and "metrics.json" in err and len(err.strip().splitlines()) == 1
