"""The machine descriptor drives every run: {3-ph, 6-ph} × {inproc, spawn} × {lockstep, realtime} logged with the
trace, and {3-ph, 6-ph} × {log, no-log}, and the real-time link budget is computed with the machine's own frames."""

from __future__ import annotations

import socket
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.machine import DUAL_THREE_PHASE, THREE_PHASE, layout_for_phases, load_machine, machine_for
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.records import TRACE_DTYPE, TRACE_DTYPE6
from pmsm_hil.hil.runlog.reader import read_metadata, read_periods, read_trace
from pmsm_hil.hil.runner.budget_check import check_realtime_budget
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario

#: (motor, controller, load N·m) of each machine kind
MACHINES = {3: ("niu2020-ipmsm", "mpcc", 7.0), 6: ("zhang2021-dtpmsm", "mptc2", 40.0)}


def _free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _cfg(phases: int, *, logging: str, target: str, mode: str, out: Path) -> RunConfig:
    motor, controller, load = MACHINES[phases]
    sc = load_scenario("steady").with_overrides(speed_rpm=1500.0, load_nm=load, settle_s=0.0, duration_s=0.02)
    link = "virtual" if target == "inproc" else f"udp:{_free_udp_port()}:{_free_udp_port()}"
    # real time on this shared 2-core machine may miss deadlines: the watchdog is widened, the plumbing is tested
    # and its misses are tolerated (the contract has its own tests)
    watchdog, tolerate = (10, 0) if mode == "lockstep" else (10**6, 10**6)
    return RunConfig(motor=load_motor(motor), scenario=sc, controller=controller, link=link, target=target,
                     mode=mode, out_dir=None if logging == "no-log" else out, log_trace=logging == "log-trace",
                     watchdog_periods=watchdog, tolerate=tolerate)


#: every machine kind with every target kind in every mode, logging its periods and its trace; the logging without
#: the trace and without a log, per machine kind: the logging is the host's (the loop's period blocks to the logger
#: process), the same code whichever target answers and however the periods are paced
MATRIX = [*((phases, "log-trace", target, mode) for phases in (3, 6) for target in ("inproc", "spawn")
            for mode in ("lockstep", "realtime")),
          *((phases, logging, "inproc", "lockstep") for phases in (3, 6) for logging in ("log", "no-log"))]


@pytest.mark.parametrize(("phases", "logging", "target", "mode"), MATRIX,
                         ids=[f"{p}-{log}-{t}-{m}" for p, log, t, m in MATRIX])
def test_run_matrix(phases: int, logging: str, target: str, mode: str, tmp_path: Path) -> None:
    cfg = _cfg(phases, logging=logging, target=target, mode=mode, out=tmp_path)
    assert cfg.machine.phases == phases
    res = run_closed_loop(cfg)
    m = res.metrics
    periods = res.outcome.periods.all()
    if mode == "lockstep" or m["deadline_misses"] == 0:
        assert m["end_reason"] == "completed", m["end_reason"]
        assert len(periods) == m["total_periods"] == 200
    else:  # a loaded machine missed deadlines: the held vector may trip the plant; it must say so
        assert m["end_reason"] == "completed" or m["end_reason"].startswith("plant trip"), m["end_reason"]
        assert len(periods) == m["total_periods"] <= 200
    assert np.isfinite(periods["i_u"]).all() == (phases == 6)
    assert ("xy_current_rms_a" in m) == (phases == 6)
    if logging == "no-log":
        assert res.mcap_path is None and not (tmp_path / "run.mcap").exists()
        return
    assert res.mcap_path == tmp_path / "run.mcap"
    assert read_metadata(res.mcap_path)["phases"] == str(phases)
    logged = read_periods(res.mcap_path)
    assert len(logged) == len(periods)
    np.testing.assert_array_equal(logged["seq"], periods["seq"])
    trace = read_trace(res.mcap_path)
    if logging == "log-trace":
        assert trace.dtype == cfg.machine.layout.trace_dtype
        assert len(trace) == len(res.outcome.trace) > 0
        np.testing.assert_array_equal(trace["i_a"], res.outcome.trace["i_a"])
    else:
        assert len(trace) == 0


@pytest.mark.parametrize(("phases", "refused"), [(3, False), (6, True)])
def test_realtime_budget_counts_the_machines_frames(phases: int, refused: bool) -> None:
    """Classic CAN at 1 Mbit/s carries 1481 Hz with three-phase frames but 1235 Hz with six-phase frames
    (one more Measurement frame): Ts = 800 µs (1250 Hz) fits the first only."""
    if refused:
        with pytest.raises(ParameterError, match="at most 1235 Hz"):
            check_realtime_budget("socketcan:vcan0", 800e-6, phases)
    else:
        check_realtime_budget("socketcan:vcan0", 800e-6, phases)


def test_realtime_run_of_a_six_phase_motor_is_budgeted_with_six_phase_frames(tmp_path: Path) -> None:
    cfg = replace(_cfg(6, logging="no-log", target="inproc", mode="realtime", out=tmp_path),
                  link="socketcan:vcan0", ts_s=800e-6)
    with pytest.raises(ParameterError, match="1235 Hz"):
        run_closed_loop(cfg)  # refused before any link is opened (no vcan needed)


def test_descriptor_layouts() -> None:
    assert machine_for(load_motor("niu2020-ipmsm")).layout is THREE_PHASE
    m6 = load_machine("zhang2021-dtpmsm")
    assert m6.layout is DUAL_THREE_PHASE and m6.phases == 6 and m6.name == "zhang2021-dtpmsm"
    assert THREE_PHASE.trace_dtype == TRACE_DTYPE and DUAL_THREE_PHASE.trace_dtype == TRACE_DTYPE6
    assert (THREE_PHASE.max_state_code, DUAL_THREE_PHASE.max_state_code) == (7, 63)
    assert layout_for_phases(6) is DUAL_THREE_PHASE
    with pytest.raises(ParameterError, match="phases: no machine layout for 5"):
        layout_for_phases(5)
