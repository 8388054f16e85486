"""The logger's ring of a run holds the whole log of a short run and is the 64 MiB default for a long one; a
short run's log through the smaller ring is complete."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.records import FRAME_DTYPE, PERIOD_DTYPE
from pmsm_hil.hil.runlog.logger import DEFAULT_RING_BYTES
from pmsm_hil.hil.runlog.reader import read_frames, read_periods
from pmsm_hil.hil.runner.run import logger_ring_bytes, run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario

MIB = 1024 * 1024


def _cfg(total_s: float, **kw: object) -> RunConfig:
    sc = load_scenario("steady").with_overrides(settle_s=total_s / 2, duration_s=total_s / 2)
    return RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc, **kw)  # type: ignore[arg-type]


def test_a_short_run_gets_a_ring_for_twice_its_log_and_a_long_one_the_default() -> None:
    short = _cfg(0.02)
    periods = round(0.02 / short.ts_s) + 1
    assert 4 * MIB <= logger_ring_bytes(short) < 16 * MIB
    assert logger_ring_bytes(short) >= 2 * periods * (PERIOD_DTYPE.itemsize + 16 * FRAME_DTYPE.itemsize)
    assert logger_ring_bytes(_cfg(2.0)) == DEFAULT_RING_BYTES
    # trace rows: one per trace step of each period, on top
    traced = replace(short, log_trace=True)
    rows = round(short.ts_s / short.trace_dt_s)
    assert logger_ring_bytes(traced) >= 2 * periods * rows * short.machine.layout.trace_dtype.itemsize
    medium = _cfg(0.3)  # above the 4 MiB floor
    assert 4 * MIB < logger_ring_bytes(medium) < logger_ring_bytes(replace(medium, log_trace=True))


def test_a_traced_run_through_the_sized_ring_logs_every_period_and_frame(tmp_path: Path) -> None:
    cfg = replace(_cfg(0.1, log_trace=True), out_dir=tmp_path)
    assert logger_ring_bytes(cfg) < DEFAULT_RING_BYTES
    res = run_closed_loop(cfg)
    assert res.metrics["end_code"] == 0, res.metrics["end_reason"]
    periods = read_periods(tmp_path / "run.mcap")
    assert len(periods) == res.metrics["total_periods"] == round(0.1 / cfg.ts_s)
    assert len(read_frames(tmp_path / "run.mcap")) >= 2 * len(periods)  # a Measurement and a Command each
