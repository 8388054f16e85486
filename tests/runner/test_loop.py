"""The native period loop (src/pmsm_hil/hil/runner/c/loop.c) gives the Python loop's records bit for bit: every field of
every period record but the measured execution times, the raw frames of the log, the trace, the metrics, and the
same ending (a silent target); runs it cannot do fall back to the Python loop with the reason."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runlog.reader import read_frames, read_periods, read_trace
from pmsm_hil.hil.runner.loop_run import python_loop_reason
from pmsm_hil.hil.runner.run import RunResult, run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.hil.sensors import SensorConfig
from pmsm_hil.protocol.codec import decode_frame
from pmsm_hil.protocol.frame import Frame

#: measured on the host's clock: differ between any two runs (and the target end's link counters: the native
#: loop's in-process core has no link)
TIMING_FIELDS = {"exec_time_ns", "exec_split_ns"}
TIMING_METRICS = {"exec_time_us", "exec_split_us", "exec_time_first_us",
                  "total_wall_time_s", "loop_rate_total_hz", "loop_rate_hz",
                  "wall_time_s", "realtime_factor", "loop", "loop_note", "safe_stop_wait_ms",
                  "target_link", "link_losses", "link_auth_dropped"}
SENSORS = SensorConfig(adc_lsb_a=0.01, noise_std_a=0.05, encoder_counts=4096, seed=3)


def _both(cfg: RunConfig, tmp_path: Path | None = None, **kw: Any) -> tuple[RunResult, RunResult]:
    runs = []
    for loop in ("python", "native"):
        out = None if tmp_path is None else tmp_path / loop
        runs.append(run_closed_loop(replace(cfg, loop=loop, out_dir=out), **kw))
    assert runs[0].metrics["loop"] == "python" and runs[1].metrics["loop"] == "native"
    return runs[0], runs[1]


def _assert_same_records(a: np.ndarray, b: np.ndarray) -> None:
    assert a.shape == b.shape and a.shape[0] > 0
    for name in a.dtype.names or ():
        if name not in TIMING_FIELDS:
            assert a[name].tobytes() == b[name].tobytes(), name
    for name in TIMING_FIELDS:  # measured, so only plausible: the firmware's steps took time
        assert (a[name][1:] > 0).any() and (b[name][1:] > 0).any(), name


def _assert_same_frames(a: np.ndarray, b: np.ndarray) -> None:
    """Same frames, bytes and all, but the Commands' measured exec_time_ns."""
    assert a.shape == b.shape and a.shape[0] > 0
    for name in ("t", "seq", "direction", "arbitration_id", "is_fd", "length"):
        assert a[name].tobytes() == b[name].tobytes(), name
    for x, y in zip(a, b, strict=True):
        fx, fy = (decode_frame(Frame(int(r["arbitration_id"]), bytes(r["data"][:r["length"]]), bool(r["is_fd"])))
                  for r in (x, y))
        assert fx[0] == fy[0]
        fx[1].pop("exec_time_ns", None)
        fy[1].pop("exec_time_ns", None)
        assert fx[1] == fy[1], fx[0]


def _assert_same_metrics(py: dict[str, Any], na: dict[str, Any]) -> None:
    assert py.keys() == na.keys()
    for key in py.keys() - TIMING_METRICS:
        assert py[key] == na[key], key


def _three(**overrides: Any) -> RunConfig:
    sc = load_scenario("speed-step").with_overrides(settle_s=0.005, duration_s=0.03, speed_step_s=0.02)
    return RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc, controller="mpcc", **overrides)


def _mirrored(**overrides: Any) -> RunConfig:
    """hv-mpfc sends mirrored sequences (the plant applies s0..s(n-1), s(n-2)..s0)."""
    return replace(_three(**overrides), controller="hv-mpfc")


def _six(**overrides: Any) -> RunConfig:
    sc = load_scenario("steady").with_overrides(speed_rpm=1500.0, load_nm=40.0, settle_s=0.005, duration_s=0.015)
    return RunConfig(motor=load_motor("zhang2021-dtpmsm"), scenario=sc, controller="mptc2", **overrides)


def test_three_phase_canfd_with_sensors_and_a_speed_step_logs_identically(tmp_path: Path) -> None:
    py, na = _both(_three(sensors=SENSORS, log_trace=True), tmp_path)
    _assert_same_records(py.outcome.periods.all(), na.outcome.periods.all())
    _assert_same_metrics(py.metrics, na.metrics)
    assert py.mcap_path is not None and na.mcap_path is not None
    _assert_same_records(read_periods(py.mcap_path), read_periods(na.mcap_path))
    _assert_same_frames(read_frames(py.mcap_path), read_frames(na.mcap_path))  # set-up and step Setpoints too
    assert read_trace(py.mcap_path).tobytes() == read_trace(na.mcap_path).tobytes()
    assert np.unique(na.outcome.periods.all()["speed_ref"]).size == 2


@pytest.mark.parametrize(("make", "link", "sensors"), [
    (_three, "virtual,fd=false", SensorConfig()),
    (_mirrored, "virtual", SensorConfig()),
    (_six, "virtual", SensorConfig()),
    (_six, "virtual,fd=false", SENSORS),
])
def test_classic_can_and_six_phases(make: Any, link: str, sensors: SensorConfig) -> None:
    py, na = _both(make(link=link, sensors=sensors))
    _assert_same_records(py.outcome.periods.all(), na.outcome.periods.all())
    _assert_same_metrics(py.metrics, na.metrics)
    if make is _mirrored:
        assert na.outcome.periods.all()["mirror"].any()


@pytest.mark.parametrize(("link", "pwm_update", "t_dead"), [
    ("virtual", "single", 0.0), ("virtual,fd=false", "double", 0.0), ("virtual", "double", 1e-6),
])
def test_foc_via_duty_cycles_logs_identically(link: str, pwm_update: str, t_dead: float) -> None:
    """foc's duty-cycle Commands (CmdDutyFd, CmdDutyA/B/C): the carrier comparison in C
    (src/pmsm_hil/hil/runner/c/pwm_duty.c) gives the oracle's records (src/pmsm_hil/hil/pwm.py) bit for bit, single and
    double update, with dead time."""
    cfg = _three(link=link, sensors=SENSORS)
    motor = cfg.motor.with_values(t_dead=t_dead, t_mpw=0.5e-6)
    cfg = replace(cfg, controller="foc", pwm_update=pwm_update, motor=motor)
    py, na = _both(cfg)
    periods = na.outcome.periods.all()
    _assert_same_records(py.outcome.periods.all(), periods)
    _assert_same_metrics(py.metrics, na.metrics)
    assert (periods["n_duties"][2:] == 3).all() and (periods["n_states"][2:] == 0).all()
    assert ((periods["duties"][2:, :3] > 0.0) & (periods["duties"][2:, :3] < 1.0)).all()


def test_load_steps_in_inertia_mode() -> None:
    sc = load_scenario("load-steps").with_overrides(settle_s=0.005, duration_s=0.03, load_step_s=0.01,
                                                    load_steps=((0.02, 2.0),))
    cfg = RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc, controller="foc")
    py, na = _both(cfg)
    _assert_same_records(py.outcome.periods.all(), na.outcome.periods.all())
    assert np.unique(na.outcome.periods.all()["load_torque"]).size == 3


def test_a_load_profile_of_many_points() -> None:
    """70 load steps (the C loop reads the profile from the caller's arrays: no fixed number of points)."""
    steps = tuple((0.005 + 0.0004 * (i + 1), float(i % 3)) for i in range(70))
    sc = load_scenario("load-steps").with_overrides(settle_s=0.005, duration_s=0.03, load_step_s=0.005,
                                                    load_steps=steps)
    py, na = _both(RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc, controller="foc"))
    _assert_same_records(py.outcome.periods.all(), na.outcome.periods.all())
    assert set(np.unique(na.outcome.periods.all()["load_torque"])) == {0.0, 1.0, 2.0, 4.0}  # the preset's 4 N·m too


def test_a_silent_target_ends_both_loops_alike() -> None:
    py, na = _both(_three(watchdog_periods=5, tolerate=100), silent_after=40)
    _assert_same_records(py.outcome.periods.all(), na.outcome.periods.all())
    _assert_same_metrics(py.metrics, na.metrics)
    assert na.metrics["end_code"] == 3 and "watchdog: target silent for 5 periods" in na.metrics["end_reason"]
    assert na.metrics["dut_violations_by_rule"]["missing"] == 5
    assert [v.as_dict() for v in py.outcome.violations] == [v.as_dict() for v in na.outcome.violations]


def test_runs_the_native_loop_cannot_do_use_the_python_loop_with_the_reason() -> None:
    assert python_loop_reason(_three()) is None
    assert python_loop_reason(_three(link="udp", target="spawn")) is None  # tests/runner/test_wire_udp.py
    assert python_loop_reason(_three(link="serial:pty", target="spawn")) is None  # test_wire_serial.py
    # python-can adapters, in-process Python and SIL targets, QEMU: the callback link (test_callback_link.py)
    assert python_loop_reason(_three(link="pcan:PCAN_USBBUS1", target="external")) is None
    assert python_loop_reason(_three(link="udp", target="inproc")) is None
    assert python_loop_reason(_three(faults="drop=0.1")) is None  # faults through the callback link
    steps = tuple((0.001 * (i + 2), float(i % 3)) for i in range(70))
    many = load_scenario("load-steps").with_overrides(settle_s=0.005, duration_s=0.1, load_step_s=0.001,
                                                      load_steps=steps)
    assert python_loop_reason(replace(_three(), scenario=many)) is None  # any number of load-profile points
    assert python_loop_reason(_three(loop="python")) == "--loop python"
    with pytest.raises(ParameterError, match="--loop must be one of"):
        _three(loop="c")
    with pytest.raises(ParameterError, match="--rt-priority"):
        _three(rt_priority=100)


def test_real_time_native_run_reports_lateness_and_what_was_refused() -> None:
    cfg = _three(mode="realtime", rt_priority=1, cpu=0, loop="native")
    res = run_closed_loop(replace(cfg, scenario=cfg.scenario.with_overrides(settle_s=0.0, duration_s=0.02)))
    m = res.metrics
    assert m["loop"] == "native" and m["end_code"] == 0 and m["total_periods"] == 200
    assert set(m["lateness_us"]) == {"median", "p99", "max"} and m["lateness_us"]["max"] >= 0.0
    assert isinstance(m["overruns"], int)
    # a refused SCHED_FIFO priority is said, never silently dropped (asked of this machine independently)
    probe = subprocess.run([sys.executable, "-c", "import os; os.sched_setscheduler(0, os.SCHED_FIFO, "
                            "os.sched_param(1))"], capture_output=True, check=False)
    refused = [w for w in m["warnings"] if w.startswith("--rt-priority 1: SCHED_FIFO not permitted")]
    assert bool(refused) == (probe.returncode != 0)


@pytest.mark.parametrize(("legs", "fd"), [(3, True), (3, False), (6, True), (6, False)])
def test_measurement_frames_equal_the_python_codec_at_ties_saturation_and_wrap(legs: int, fd: bool) -> None:
    """Raw values rounded half to even (0.0005 A → 0, 0.0015 A → 2), saturated (±40 A), the angle wrapped
    (−0.1 rad, 7 rad, 2π), seq wrapped: the C frames are the Python codec's, byte for byte."""
    from pmsm_hil.hil._loop_native import ffi, lib

    from pmsm_hil.hil.machine import layout_for_phases
    from pmsm_hil.hil.runner.loop_config import fill_codec
    from pmsm_hil.protocol.codec import FrameCodec
    from pmsm_hil.protocol.messages import Measurement, Measurement6

    c = ffi.new("nl_config_t *")
    c.machine.legs, c.machine.vdc = legs, 48.005
    fill_codec(c.target_link.codec, lib, layout_for_phases(legs).measurement, fd)
    codec = FrameCodec("canfd" if fd else "can")
    step = 0.01 if legs == 6 else 0.001
    cases = [(0.5 * step, 1.5 * step, -2.5 * step, -0.1), (40.0 * legs, -400.0, 1e308, 7.0),
             (0.0, -0.0, 0.0, 2 * np.pi)]
    out = ffi.new("hil_core_frame_t[3]")
    n, field, value = ffi.new("int *"), ffi.new("int32_t *"), ffi.new("double *")
    for seq, (a, b, cc, theta) in zip((0, 255, 65535), cases, strict=True):
        currents = [a, b, cc, -a, -b, cc][:legs]
        omega = -700.0 if seq == 255 else 104.72
        assert lib.nl_encode_meas(c, seq, ffi.new("double[]", currents), theta, omega, out, n, field, value) == 0
        msg = (Measurement(seq, *currents, theta_e=theta, omega_m=omega, vdc=48.005) if legs == 3
               else Measurement6(seq, *currents, theta_e=theta, omega_m=omega, vdc=48.005))
        want = codec.encode(msg)
        got = [(int(out[j].id), bytes(ffi.buffer(out[j].data, out[j].len)), bool(out[j].fd)) for j in range(n[0])]
        assert got == [(f.arbitration_id, f.data, f.is_fd) for f in want]
    nan = [float("nan")] * legs
    assert lib.nl_encode_meas(c, 1, ffi.new("double[]", nan), 0.0, 0.0, out, n, field, value) == -1
    assert field[0] == 1  # i_a: the run ends as the Python codec's EncodeError names it


def test_ctrl_c_while_draining_ends_both_loops_as_interrupted() -> None:
    for loop in ("python", "native"):
        raised: list[int] = []

        def interrupt(periods: np.ndarray, raised: list[int] = raised) -> None:
            if not raised:  # once, as a Ctrl-C: the final block still reaches the sink
                raised.append(periods.shape[0])
                raise KeyboardInterrupt

        # The C loop runs in its own thread while this thread drains its blocks: on a loaded machine (load 7) the
        # drain may first run after the loop has done thousands of periods, so a 0.3 s run (3050 periods, ~10 ms
        # of loop) could end before the Ctrl-C reaches it. 30 s (300 050 periods, >= 1 s of loop at full speed)
        # leaves the interrupt the whole run to land; it lands at the first block, so the test stays short.
        cfg = _three(loop=loop)
        cfg = replace(cfg, scenario=cfg.scenario.with_overrides(duration_s=30.0))
        total = round(cfg.scenario.total_s / cfg.ts_s)
        res = run_closed_loop(cfg, live=interrupt)
        assert res.metrics["loop"] == loop
        assert res.metrics["end_code"] == 130 and res.metrics["end_reason"] == "interrupted (Ctrl-C or SIGTERM)"
        assert res.outcome.target_disabled and res.outcome.safe_state
        assert 1000 <= raised[0] <= res.outcome.completed_periods < total


def test_rt_options_on_the_python_loop_are_said_not_applied() -> None:
    res = run_closed_loop(_three(loop="python", rt_priority=10, cpu=0))
    assert "--rt-priority and --cpu: not applied, they act on the native loop and this run used the Python loop" \
        in res.metrics["warnings"]
    assert res.metrics["loop_note"] == "--loop python"


def test_bench_realtime_prints_both_loops_side_by_side(capsys: pytest.CaptureFixture[str]) -> None:
    from pmsm_hil.app.cli.main import main

    assert main(["bench", "realtime", "--duration", "0.005", "--repeats", "1", "--links", "inproc"]) == 0
    out = capsys.readouterr().out
    assert "load average" in out and "overruns/100k" in out and "p99.99 µs" in out
    rows = [line.split() for line in out.splitlines() if line.strip().startswith("inproc ")]
    assert [r[1] for r in rows] == ["python", "native"] and all(r[-1] == "50" for r in rows)  # periods per loop
    assert "floor: a bare C busy loop" in out  # what the machine itself allows, beside the loops


def test_gap_probe_counts_the_time_a_busy_loop_did_not_run() -> None:
    from pmsm_hil.app.cli.bench_realtime import gap_floor

    floor = gap_floor(0.05, 100e-6, 0, None)
    assert floor is not None and floor["refused_errno"] == 0
    assert 0.0 <= floor["lost_pct"] <= 100.0 and floor["max_gap_us"] >= 0.0
    assert floor["gaps_over_10us"] >= floor["gaps_over_threshold_per_100k"] * 0.05 / 100e-6 / 1e5 - 1e-9


def test_dyno_speed_step_and_the_candidate_diagnostic() -> None:
    """Dyno mechanics follow the new reference in the same period; fcs-mpc-2's restricted-vs-full candidate
    diagnostic (read from the firmware after each step) is counted alike."""
    sc = load_scenario("dyno-steady").with_overrides(settle_s=0.005, duration_s=0.03, speed_step_s=0.02,
                                                     initial_speed_rpm=1000.0, speed_rpm=1500.0)
    py, na = _both(RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc, controller="fcs-mpc-2"))
    _assert_same_records(py.outcome.periods.all(), na.outcome.periods.all())
    _assert_same_metrics(py.metrics, na.metrics)
    assert na.metrics["candidate_miss_rate"] is not None
    assert np.unique(na.outcome.periods.all()["omega_m"]).size == 2


def _controller_case(name: str, phases: int) -> RunConfig:
    """A short run of controller `name` on the machine its paper uses (both links' frame profiles alternate)."""
    if phases == 6:
        return replace(_six(sensors=SENSORS), controller=name)
    motor = {"3vmpc": "xiao2023-spmsm", "hv-mpfc": "xiao2023-spmsm", "im-foc": "im-2k2"}.get(name, "niu2020-ipmsm")
    sc = load_scenario("speed-step").with_overrides(settle_s=0.003, duration_s=0.015, speed_step_s=0.01)
    return RunConfig(motor=load_motor(motor), scenario=sc, controller=name, sensors=SENSORS)


def _reference_controllers() -> list[tuple[str, int]]:
    from pmsm_hil.sim_target.firmware import CONTROLLERS

    return [(c.name, c.phases) for c in CONTROLLERS if c.implemented and c.phases in (3, 6)]


@pytest.mark.parametrize(("name", "phases"), _reference_controllers())
def test_every_reference_controller_gives_the_python_loops_records(name: str, phases: int) -> None:
    """The oracle: the C loop (machine kernels called through their tables) against the Python ClosedLoop, for
    every reference controller, three- and six-phase (im-foc on the induction machine), CAN FD and classic CAN."""
    link = "virtual" if sum(map(ord, name)) % 2 else "virtual,fd=false"
    py, na = _both(replace(_controller_case(name, phases), link=link))
    _assert_same_records(py.outcome.periods.all(), na.outcome.periods.all())
    _assert_same_metrics(py.metrics, na.metrics)


def test_the_c_record_structs_are_generated_from_the_dtypes() -> None:
    """src/pmsm_hil/hil/runner/c/records.h is what `python -m pmsm_hil.hil.gen_records` writes from PERIOD_DTYPE /
    FRAME_DTYPE, and the compiled loop's structs have the dtypes' sizes (the header also checks every offset at compile
    time)."""
    from pmsm_hil.hil._loop_native import lib

    from pmsm_hil.hil import gen_records
    from pmsm_hil.hil.records import FRAME_DTYPE, PERIOD_DTYPE

    assert gen_records.main(["--check"]) == 0
    assert (lib.nl_sizeof_period(), lib.nl_sizeof_frame()) == (PERIOD_DTYPE.itemsize, FRAME_DTYPE.itemsize)
