"""Control periods of 25 and 50 µs: the closed loop holds speed and torque in process and over UDP to
the native target, every period of a logged run is in its MCAP, the C loop's lateness histogram counts every
period start, and the link budget says which links carry 40 kHz."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runlog.reader import read_periods
from pmsm_hil.hil.runner.budget_check import check_realtime_budget
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario


def _steady(ts: float, duration: float = 0.1, settle: float = 0.1, **kw: object) -> RunConfig:
    sc = load_scenario("steady").with_overrides(settle_s=settle, duration_s=duration)
    return RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc, controller="mpcc", ts_s=ts, loop="native",
                     **kw)  # type: ignore[arg-type]


def _holds(metrics: dict[str, object], ts: float, periods: int) -> None:
    assert metrics["end_code"] == 0, metrics.get("end_reason")
    assert metrics["total_periods"] == periods
    assert metrics["speed_mean_rpm"] == pytest.approx(1500.0, rel=0.01)  # type: ignore[arg-type]
    assert metrics["torque_mean_nm"] == pytest.approx(7.0, rel=0.03)  # type: ignore[arg-type]
    # f_av and the THD window follow Ts: the switching frequency stays below the control rate, the THD is finite
    assert 0.0 < metrics["switching_freq_khz"] < 1e-3 / ts  # type: ignore[operator]
    assert 0.0 < metrics["current_thd_pct"] < 10.0  # type: ignore[operator]


@pytest.mark.parametrize("ts", [25e-6, 50e-6])
def test_closed_loop_in_process_holds_speed_and_torque(ts: float) -> None:
    res = run_closed_loop(_steady(ts))
    _holds(res.metrics, ts, round(0.2 / ts))


@pytest.mark.parametrize("ts", [25e-6, 50e-6])
def test_closed_loop_over_udp_to_the_native_target_holds_speed_and_torque(ts: float) -> None:
    res = run_closed_loop(_steady(ts, duration=0.05, settle=0.1, link="udp", target="spawn"))
    _holds(res.metrics, ts, round(0.15 / ts))
    assert res.metrics["link_spec"] == "udp"


def test_every_period_of_a_logged_run_at_25_us_is_in_the_mcap(tmp_path: Path) -> None:
    """Lockstep and real time, in process, logging on: the MCAP holds end_period + 1 periods, in order."""
    for mode in ("lockstep", "realtime"):
        res = run_closed_loop(_steady(25e-6, duration=0.1, settle=0.05, mode=mode, out_dir=tmp_path / mode))
        assert res.mcap_path is not None and res.metrics["end_code"] == 0
        periods = read_periods(res.mcap_path)
        assert len(periods) == res.outcome.completed_periods == round(0.15 / 25e-6)
        np.testing.assert_array_equal(periods["seq"], np.arange(len(periods)))


def test_the_c_loop_counts_every_period_start_in_its_lateness_histogram() -> None:
    res = run_closed_loop(_steady(50e-6, duration=0.02, settle=0.0, mode="realtime"))
    hist = res.outcome.lateness_hist_1us
    assert hist is not None and hist.shape == (1024,)
    assert int(hist.sum()) == res.outcome.completed_periods == res.outcome.lateness_us.n
    worst = min(int(res.outcome.lateness_us.maximum()), 1023)  # [µs], the last bin open-ended
    assert hist[worst] > 0 and not hist[worst + 1:].any()
    # the bins hold what the per-block lateness holds
    edges = np.array([*(1000 * np.arange(1024)), np.iinfo(np.int64).max], dtype=np.int64)
    np.testing.assert_array_equal(res.outcome.lateness_us.histogram(edges), hist)


def test_lockstep_run_has_no_lateness_histogram() -> None:
    assert run_closed_loop(_steady(25e-6, duration=0.01, settle=0.0)).outcome.lateness_hist_1us is None


@pytest.mark.parametrize(("spec", "ts", "refused"), [
    ("socketcan:vcan0", 50e-6, "675 µs on the wire"),  # classic CAN, 1 Mbit/s: 5 frames
    ("socketcan:vcan0", 25e-6, "675 µs on the wire"),
    ("socketcan:vcan0,fd=true", 25e-6, "154 µs on the wire"),  # CAN FD 1 / 5 Mbit/s
    # serial at 12 MBd: 58 µs with the authentication trailer of spawned targets (the default), 48 µs without
    ("serial:pty,baudrate=12000000", 25e-6, "58 µs on the wire"),
    ("serial:pty,baudrate=12000000", 50e-6, "58 µs on the wire"),
    ("serial:pty,baudrate=12000000,auth=off", 25e-6, "48 µs on the wire"),
    ("serial:pty,baudrate=12000000,auth=off", 50e-6, None),
])
def test_realtime_link_budget_at_small_ts(spec: str, ts: float, refused: str | None) -> None:
    if refused is None:
        check_realtime_budget(spec, ts)
    else:
        with pytest.raises(ParameterError, match=refused):
            check_realtime_budget(spec, ts)


def test_a_realtime_run_on_classic_can_at_25_us_is_refused_with_the_reason() -> None:
    with pytest.raises(ParameterError, match=r"--link socketcan:vcan0: 2 \+ 3 frames per period need 675 µs"):
        run_closed_loop(replace(_steady(25e-6), link="socketcan:vcan0", target="external", mode="realtime"))


def test_link_budget_cli_at_25_us(capsys: pytest.CaptureFixture[str]) -> None:
    from pmsm_hil.app.cli.main import main

    assert main(["link-budget", "--link", "can", "--ts", "25e-6"]) == 1
    cap = capsys.readouterr()
    assert "too slow: can carries at most 1481 Hz of closed loop, --ts 2.5e-05 s is 40000 Hz: 2 + 3 frames per " \
        "period need 675.0 µs on the wire" in cap.err
    assert main(["link-budget", "--link", "canfd", "--ts", "25e-6", "--json"]) == 1
    assert '"wire_time_per_period_us"' in capsys.readouterr().out
    assert main(["link-budget", "--link", "udp", "--ts", "25e-6"]) == 0  # 1 Gbit/s Ethernet: 1.6 µs
    out = capsys.readouterr().out
    assert "udp (Ethernet 1000000000 bit/s" in out and "1.6 µs on the wire" in out and "(fits)" in out
    assert main(["link-budget", "--link", "serial", "--baud", "12000000", "--ts", "50e-6"]) == 0
    assert main(["link-budget", "--link", "can", "--ts", "0"]) == 2
    assert "--ts must be a positive number" in capsys.readouterr().err


def test_target_rt_priority_is_for_the_native_target_only(capsys: pytest.CaptureFixture[str]) -> None:
    from pmsm_hil.app.cli.main import main

    assert main(["target", "--link", "udp:47990:47991", "--rt-priority", "5"]) == 2
    assert "--rt-priority: with --native only" in capsys.readouterr().err
    assert main(["target", "--native", "--link", "udp:47990:47991", "--rt-priority", "100"]) == 2
    assert "--rt-priority must be 1..99, got 100" in capsys.readouterr().err


def test_a_spawned_native_target_runs_at_the_loops_priority(monkeypatch: pytest.MonkeyPatch) -> None:
    """Real time under --rt-priority over UDP: the spawned native target is asked for the same SCHED_FIFO
    priority (its command line), so the pair is scheduled alike."""
    from pmsm_hil.hil.runner import target_setup

    seen: list[int] = []
    spawn = target_setup._spawn_target

    def record(*args: object, rt_priority: int = 0, **kw: object) -> object:
        seen.append(rt_priority)
        return spawn(*args, rt_priority=rt_priority, **kw)  # type: ignore[arg-type]

    monkeypatch.setattr(target_setup, "_spawn_target", record)
    cfg = _steady(50e-6, duration=0.005, settle=0.0, link="udp", target="spawn", tolerate=10**6,
                  watchdog_periods=10**6)
    run_closed_loop(replace(cfg, mode="realtime", rt_priority=1))
    run_closed_loop(cfg)  # lockstep: no priority asked
    assert seen == [1, 0]


@pytest.mark.parametrize("name", ["accel", "dyno-steady", "load-step", "load-steps", "speed-step", "steady"])
def test_every_bundled_scenario_runs_at_25_us_as_at_100_us(name: str) -> None:
    """The scenarios' times (steps, load points, settling) are in seconds, never in periods: at 25 µs each runs
    four times the periods and reaches the speed and torque it reaches at 100 µs; the current THD is lower
    (a finer control period), f_av higher."""
    sc = load_scenario(name)
    runs = {ts: run_closed_loop(RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc, controller="mpcc",
                                          ts_s=ts, loop="native")).metrics for ts in (25e-6, 100e-6)}
    fine, coarse = runs[25e-6], runs[100e-6]
    assert fine["end_code"] == coarse["end_code"] == 0
    assert fine["total_periods"] == 4 * coarse["total_periods"] == round((sc.settle_s + sc.duration_s) / 25e-6)
    assert fine["speed_mean_rpm"] == pytest.approx(coarse["speed_mean_rpm"], rel=0.005)
    assert fine["torque_mean_nm"] == pytest.approx(coarse["torque_mean_nm"], rel=0.02)
    if name in ("steady", "dyno-steady"):
        assert fine["current_thd_pct"] < coarse["current_thd_pct"]
    else:  # a speed step, an acceleration or a load step's speed dip in the window: no single fundamental
        assert fine["current_thd_pct"] is None and coarse["current_thd_pct"] is None
        assert "changes by" in coarse["not_applicable"]["current_thd_pct"]
    assert fine["switching_freq_khz"] > coarse["switching_freq_khz"]


def test_which_controllers_fit_a_period_on_the_mcu() -> None:
    """`hil bench controllers --board mps2-an386` says per Ts which controllers fit: the worst estimated step
    may take half the period (figures of the 2026-11-26 run: mpcc 6.58 µs max, mptc2 21.50 µs)."""
    from pmsm_hil.app.cli.bench_controllers import format_mcu
    from pmsm_hil.app.cli.bench_mcu import McuFigures, fits_ts

    figs = [McuFigures(1, "mpcc", {"median": 1036, "p99": 1058, "max": 1106}, {"median": 6.17, "max": 6.58}),
            McuFigures(8, "mptc2", {"median": 3557, "p99": 3599, "max": 3612}, {"median": 21.17, "max": 21.50})]
    assert [[f.name for f in side] for side in fits_ts(figs, 25.0)] == [["mpcc"], ["mptc2"]]
    assert [[f.name for f in side] for side in fits_ts(figs, 50.0)] == [["mpcc", "mptc2"], []]
    lines = format_mcu(figs, None, 168e6, 200)
    assert "  Ts = 25 µs (40 kHz) at 168 MHz: can mpcc; cannot mptc2 (needs ≥ 43.0 µs)" in lines
    assert "  Ts = 50 µs (20 kHz) at 168 MHz: can mpcc, mptc2; cannot none" in lines


@pytest.mark.timing
def test_the_logger_keeps_up_with_real_time_at_25_us() -> None:
    """The run logger takes period records and their frames faster than a real-time run at 40 kHz makes them,
    with margin (measured 165–234k periods/s at load 8–16 on 2 vCPUs), so a real-time run at 25 µs never waits
    for it; lockstep throughput with logging (the 150k goal) is a quiet-machine figure (hil bench loop)."""
    from pmsm_hil.app.bench.logger_limit import logger_limit

    limit = logger_limit(100_000)
    assert limit.periods_per_s > 40_000
    assert 20.0 < limit.bytes_per_period < 400.0  # lz4-compressed records and frames, not an empty file
