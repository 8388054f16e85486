"""Shared fixtures: one short logged closed-loop run streamed live to an .rrd at the same time."""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass, replace
from pathlib import Path

import pytest

from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import RunResult, run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario

if importlib.util.find_spec("rerun") is None:  # looked up, not imported: every worker collects this folder
    pytest.skip("rerun-sdk is not installed", allow_module_level=True)


def short_config(out_dir: Path | None, controller: str = "mpcc") -> RunConfig:
    """700 periods (20 ms settling + 50 ms window) of the default demo."""
    scenario = load_scenario("steady").with_overrides(settle_s=0.02, duration_s=0.05)
    return RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=scenario, controller=controller, out_dir=out_dir,
                     log_trace=True)


@dataclass
class LiveRun:
    result: RunResult
    rrd: Path
    run_dir: Path
    periods: int


@pytest.fixture(scope="session")
def live_run(tmp_path_factory: pytest.TempPathFactory) -> LiveRun:
    from pmsm_hil.dashboards.live import LiveRerun
    from pmsm_hil.dashboards.recording import RerunTargets

    tmp = tmp_path_factory.mktemp("live")
    cfg = short_config(tmp / "run")
    rrd = tmp / "live.rrd"
    with LiveRerun(RerunTargets(save=rrd), vdc=cfg.motor.vdc, ts_s=cfg.ts_s) as live:
        result = run_closed_loop(cfg, live=live.submit_periods)
    assert live.final_stats is not None
    return LiveRun(result, rrd, tmp / "run", int(live.final_stats["periods"]))


@pytest.fixture(scope="session")
def second_run_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("second") / "run"
    run_closed_loop(replace(short_config(out, "fcs-mpc-1")))
    return out
