"""`hil bench realtime` at several control periods: in process and over UDP to the native target,
beside the floor of the same run, the OSADL-style histogram (CSV and PNG) and a load started beside it."""

from __future__ import annotations

import csv
import json
import subprocess
import sys
from pathlib import Path

import pytest

from pmsm_hil.app.bench.load_process import load_beside
from pmsm_hil.app.bench.realtime import floor_ratio
from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.errors import ParameterError


def test_two_periods_both_links_histogram_and_load(tmp_path: Path) -> None:
    """The `hil` process of a user: its real-time runs and floors lock the process's memory (mlockall), seconds of
    system time in a pytest worker with gigabytes mapped, a fraction of that in a `hil` process."""
    prefix = tmp_path / "report" / "latency"
    # a load that outlives the bench: at load 10 the bench took 125 s, and `sleep 60` ended before it (exited early)
    argv = ["bench", "realtime", "--ts", "50e-6", "--ts", "25e-6", "--duration", "0.02", "--repeats", "1",
            "--histogram", str(prefix), "--load-cmd", "sleep 3600", "--json", str(tmp_path / "f.json")]
    proc = subprocess.run([sys.executable, "-m", "pmsm_hil.app.cli.main", *argv], capture_output=True, text=True,
                          timeout=600, check=False)
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    assert "Ts = 50 µs (20 kHz)" in out and "Ts = 25 µs (40 kHz)" in out
    assert "load: `sleep 3600`" in out and "load average (1 min)" in out
    for link in ("inproc", "udp"):
        rows = [line.split() for line in out.splitlines() if line.strip().startswith(f"{link} ")]
        native = [r for r in rows if r[1] == "native"]
        assert len(native) == 2 and all(int(r[-1]) > 0 for r in native), out
        if link == "inproc":  # in process a period never misses its Command: every run completes
            assert [r[-1] for r in native] == ["400", "800"]  # periods at 50 and 25 µs
        assert f"goal ({link}, C loop): p99 ≤ 2 µs" in out
    assert out.count("floor: a bare C busy loop") == 2
    assert out.count("miss floor (udp): a bare C UDP exchange paced at Ts") == 2  # beside the udp rows' misses
    figures = json.loads((tmp_path / "f.json").read_text())
    assert [p["ts_s"] for p in figures["points"]] == [50e-6, 25e-6]
    for point, periods in zip(figures["points"], (400, 800), strict=True):
        miss_floor = point["udp_miss_floor"]  # paced for the runs' duration at their Ts
        assert miss_floor["periods"] == periods and 0 <= miss_floor["late"] <= periods
        udp = point["udp"]["native"]
        assert udp["misses_per_100k"] == pytest.approx(1e5 * udp["deadline_misses"] / udp["periods"])
    assert figures["load_cmd"]["command"] == "sleep 3600" and figures["load_cmd"]["exited_early"] is None
    with prefix.with_suffix(".csv").open(encoding="utf-8") as f:
        table = list(csv.reader(f))
    assert table[0][:2] == ["bin_start_us", "bin_end_us"] and "Ts 25 µs udp native" in table[0]
    assert len(table) == 1 + 1024 and table[-1][1] == ""  # 1 µs bins, the last open-ended
    col = table[0].index("Ts 50 µs inproc native")
    assert sum(int(row[col]) for row in table[1:]) == 400  # every period start counted
    col = table[0].index("Ts 25 µs udp native")
    assert sum(int(row[col]) for row in table[1:]) == figures["points"][1]["udp"]["native"]["periods"]
    col = table[0].index("Ts 25 µs floor (bare C busy loop, gaps)")  # the machine's own, beside the loops
    assert sum(int(row[col]) for row in table[1:]) > 0
    assert prefix.with_suffix(".png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_bad_links_and_a_load_that_does_not_run_are_one_line_errors(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "realtime", "--links", "can", "--duration", "0.01"]) == 2
    assert "--links: can: expected a comma list of inproc, udp" in capsys.readouterr().err
    with pytest.raises(ParameterError, match="--load-cmd: cannot start 'no-such-command-hil'"), \
            load_beside("no-such-command-hil --x"):
        pass
    with pytest.raises(ParameterError, match=r"--load-cmd: `true` exited \(code 0\) before the measurement"), \
            load_beside("true"):
        pass


def test_load_report_counts_the_cpu_the_load_used() -> None:
    import time

    from pmsm_hil.app.bench.load_process import _cpu_seconds

    with load_beside("python3 -c 'while True: pass'") as load:
        assert load is not None
        # until the burner got 0.1 CPU-s in the block (a busy machine gives it less than a CPU: wait, don't guess)
        cpu0, t0 = _cpu_seconds(load.pid), time.monotonic()
        while _cpu_seconds(load.pid) - cpu0 < 0.1 and time.monotonic() - t0 < 120:
            time.sleep(0.05)
        time.sleep(0.1)  # the block lasts at least this long after it (0.5 s was 0.4 CPU-s more of the burner)
    assert load.exited_early is None
    assert load.cpu_s >= 0.1 and load.wall_s >= 0.1
    assert load.cpu_s <= load.wall_s + 0.02  # one busy thread: at most one CPU (and a clock tick at either end)
    assert "CPUs busy" in load.describe()


def test_floor_ratio() -> None:
    assert floor_ratio(0.0, 0.0) == 1.0
    assert floor_ratio(5.0, 0.0) == float("inf")
    assert floor_ratio(10.0, 5.0) == 2.0
    assert floor_ratio(None, 5.0) is None


def test_the_floor_probe_bins_every_gap() -> None:
    from pmsm_hil.app.bench.realtime import gap_floor

    floor = gap_floor(0.02, 25e-6, 0, None)
    assert floor is not None
    hist = floor["histogram_1us"]
    worst = min(int(floor["max_gap_us"]), 1023)
    assert len(hist) == 1024 and hist[worst] > 0 and not any(hist[worst + 1:])
    assert hist[0] > sum(hist[1:])  # almost every clock read follows the previous one within 1 µs
    assert sum(hist[12:]) >= floor["gaps_over_threshold_per_100k"] * (0.02 / 25e-6) / 1e5  # gaps > 12.5 µs
