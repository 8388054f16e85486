"""Cross-process targets (UDP, pty serial), real-time mode, link-budget refusal, SIGKILL durability."""

from __future__ import annotations

import os
import signal
import socket
import time
from dataclasses import replace
from pathlib import Path

import pytest

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runlog.reader import read_periods
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario
from tests.runner.foreign_zygote import ForeignTarget
from tests.runner.hil_zygote import start_hil


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _cfg(**kw: object) -> RunConfig:
    sc = load_scenario("steady").with_overrides(settle_s=0.1, duration_s=0.1)
    return replace(RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc), **kw)  # type: ignore[arg-type]


def _assert_holds_operating_point(metrics: dict[str, object]) -> None:
    assert metrics["end_reason"] == "completed"
    assert abs(float(metrics["speed_mean_rpm"]) - 1500.0) <= 15.0  # type: ignore[arg-type]
    assert abs(float(metrics["torque_mean_nm"]) - 7.0) <= 0.14  # type: ignore[arg-type]


def test_same_scenario_with_target_process_over_udp() -> None:
    a, b = _free_udp_port(), _free_udp_port()
    host = f"udp:{a}:{b}"
    inproc = run_closed_loop(_cfg()).metrics
    # the spawned target takes the mirrored channel: the runner passes the same spec with role=target
    res = run_closed_loop(_cfg(link=host, target="spawn"))
    _assert_holds_operating_point(res.metrics)
    assert res.metrics["link"]["lost"] == 0
    # the firmware is the same C code fed the same quantised frames: identical control decisions
    assert res.metrics["torque_mean_nm"] == pytest.approx(inproc["torque_mean_nm"], abs=1e-9)


def test_same_scenario_with_target_process_over_pty_serial() -> None:
    res = run_closed_loop(_cfg(link="serial:pty"))
    _assert_holds_operating_point(res.metrics)
    assert res.metrics["link"]["crc_errors"] == 0


def test_realtime_mode_in_process_reports_lateness() -> None:
    res = run_closed_loop(_cfg(mode="realtime"))
    _assert_holds_operating_point(res.metrics)
    lat = res.metrics["lateness_us"]
    assert set(lat) == {"median", "p99", "max"} and lat["median"] >= 0.0
    hist = res.metrics["lateness_histogram_us"]
    assert sum(hist["counts"]) == res.metrics["total_periods"]  # every period start in one bin
    over = sum(c for e, c in zip(hist["edges_us"], hist["counts"], strict=True) if e >= 100.0)
    assert over <= res.metrics["overruns"]  # starts ≥ 100 µs late are overruns (threshold 50 µs)
    # pacing: the periods take the simulated time, or - on a loaded machine - the periods that started late
    # are counted as overruns and the summary warns (never a silent "0 misses"). The paced span, not the
    # run's wall time: that also holds the start-up (mlockall: tens of ms) and the safe stop.
    paced = res.outcome.paced_time_s
    assert 0.2 - 1.01e-4 <= paced <= res.outcome.wall_time_s
    if paced != pytest.approx(0.2, abs=0.01):
        assert res.metrics["overruns"] > 0 and any("real time" in w for w in res.metrics["warnings"])
    assert res.metrics["overrun_threshold_us"] == pytest.approx(50.0)


def test_realtime_over_udp_starts_with_a_synchronising_period() -> None:
    """A spawned target wakes from idle and runs its code the first time at period 0 (cold: > Ts here, every run
    failed at period 0 before): period 0's Command is awaited as in lockstep and the wall clock starts after it."""
    res = run_closed_loop(_cfg(mode="realtime", link=f"udp:{_free_udp_port()}:{_free_udp_port()}", target="spawn",
                               tolerate=10_000))  # later periods may miss on a loaded machine
    sync = res.metrics["realtime_sync_us"]
    assert isinstance(sync, float) and sync > 0.0
    assert not any(v["period"] == 0 for v in res.metrics["dut_violation_list"]), res.metrics["dut_violation_list"][:1]
    assert res.metrics["end_period"] >= 1  # (a loaded machine may end it later by the watchdog: not the point)
    inproc = run_closed_loop(_cfg(mode="realtime")).metrics
    assert inproc["realtime_sync_us"] is None  # in process: nothing to synchronise


def test_realtime_refuses_a_link_that_cannot_carry_the_rate() -> None:
    with pytest.raises(ParameterError, match="at most 1481 Hz"):
        run_closed_loop(_cfg(mode="realtime", link="socketcan:can0,bitrate=1000000"))


def _start_logged_run(out: Path, min_bytes: int) -> tuple[ForeignTarget, Path]:
    """A long `hil run` in a process of its own (forked with its imports made: tests/runner/hil_zygote.py; the
    signal comes mid-run), returned once its MCAP holds min_bytes."""
    proc = start_hil(["run", "--duration", "30", "--settle", "0", "--out", str(out)], out.with_name("stderr"))
    mcap = out / "run.mcap"
    deadline = time.monotonic() + 60
    while (not mcap.exists() or mcap.stat().st_size < min_bytes) and time.monotonic() < deadline:
        time.sleep(0.1)
    return proc, mcap


def _ppid(stat: Path) -> int:
    """The parent pid in a /proc/PID/stat, 0 if the process is gone or a zombie."""
    try:
        fields = stat.read_text().rsplit(")", 1)[1].split()
    except OSError:
        return 0
    return 0 if fields[0] == "Z" else int(fields[1])


def test_sigkill_of_a_run_leaves_a_readable_mcap(tmp_path: Path) -> None:
    # ≈ 220 bytes a period on disk: the kill comes once the file holds more than the 5000 periods checked
    proc, mcap = _start_logged_run(tmp_path / "run", 1_500_000)
    children = [stat.parent.name for stat in Path("/proc").glob("[0-9]*/stat")  # the logger, resource tracker
                if _ppid(stat) == proc.pid]
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    deadline = time.monotonic() + 60  # the logger notices its parent died and finalises the file, then ends
    while any(_ppid(Path(f"/proc/{pid}/stat")) for pid in children) and time.monotonic() < deadline:
        time.sleep(0.02)
    periods = read_periods(mcap)
    assert len(periods) > 5000
    assert (periods["seq"][:100] == range(100)).all()
    assert abs(periods["omega_m"][-1] * 60 / (2 * 3.14159265) - 1500) < 15


def test_sigterm_finalises_the_mcap(tmp_path: Path) -> None:
    from mcap.reader import make_reader

    proc, mcap = _start_logged_run(tmp_path / "run", 100_000)
    proc.send_signal(signal.SIGTERM)
    assert proc.wait(timeout=60) == 130
    with mcap.open("rb") as f:
        summary = make_reader(f).get_summary()  # needs the footer: only a finalised file has one
    assert summary is not None and summary.statistics is not None
    assert summary.statistics.message_count > 1000
