"""Orchestrates one closed-loop run: target, plant, logger, loop, metrics and outputs."""

from __future__ import annotations

import json
import math
import signal
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np
from pmsm_hil.hil.errors import HilError
from pmsm_hil.hil.metrics.summary import compute_run_metrics
from pmsm_hil.hil.runner.budget_check import check_realtime_budget
from pmsm_hil.hil.runner.closed_loop import ClosedLoop, LoopOutcome
from pmsm_hil.hil.runner.plant_setup import build_plant
from pmsm_hil.hil.runner.recorder import ByteRecords
from pmsm_hil.hil.runner.run_config import RunConfig, controller_id
from pmsm_hil.hil.runner.target_setup import TargetConnection, connect_target


@dataclass(slots=True)
class RunResult:
    """Metrics (the `--json` content), how the run ended and where its files are."""

    metrics: dict[str, Any]
    outcome: LoopOutcome
    mcap_path: Path | None


@contextmanager
def _terminate_as_interrupt() -> Iterator[None]:
    """SIGTERM behaves like Ctrl-C so the logger is finalised on both."""
    def handler(signum: int, frame: FrameType | None) -> None:
        raise KeyboardInterrupt

    try:
        previous = signal.signal(signal.SIGTERM, handler)
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _open_logger(cfg: RunConfig) -> tuple[Any, Path | None]:
    if cfg.out_dir is None:
        return None, None
    from pmsm_hil.hil.runlog.logger import RunLogger

    cfg.out_dir.mkdir(parents=True, exist_ok=True)
    path = cfg.out_dir / "run.mcap"
    meta = {"motor": cfg.motor.name, "controller": cfg.controller, "scenario": cfg.scenario.name,
            "ts_s": repr(cfg.ts_s), "link": cfg.link, "mode": cfg.mode, "seed": str(cfg.seed),
            "speed_rpm": repr(cfg.scenario.speed_rpm), "load_nm": repr(cfg.scenario.load_nm),
            "pole_pairs": str(cfg.motor.pole_pairs), "phases": str(cfg.machine.phases)}
    return RunLogger(path, metadata=meta, trace_dtype=cfg.machine.layout.trace_dtype), path


def run_closed_loop(cfg: RunConfig, *, silent_after: int | None = None,
                    live: Callable[[np.ndarray], None] | None = None) -> RunResult:
    """Run the scenario against the target named by cfg.link/cfg.target; returns metrics.

    `live`: optional consumer of each PERIOD_DTYPE block (~1000 periods), e.g. the live dashboard."""
    cid = controller_id(cfg.controller)
    if cfg.mode == "realtime":
        check_realtime_budget(cfg.link, cfg.ts_s, cfg.machine.phases)
    logger, mcap_path = _open_logger(cfg)
    conn: TargetConnection | None = None
    try:
        with _terminate_as_interrupt():
            conn = connect_target(cfg, silent_after=silent_after)
            conn.client.configure(cfg.target_parameters())
            plant = build_plant(cfg)

            def sink(periods: ByteRecords, frames: ByteRecords, trace: Any) -> None:
                block = periods.take()
                if live is not None:
                    live(block)
                if logger is None:
                    return
                logger.submit_periods(block)
                if len(frames):
                    logger.submit_frames(frames.take())

            use_sink = logger is not None or live is not None
            loop = ClosedLoop(cfg, plant, conn.client, cid, inproc_result=conn.inproc_result,
                              record_frames=logger is not None, sink=sink if use_sink else None)
            outcome = loop.run()
            conn.client.check_faults()
            if use_sink:
                sink(outcome.periods, outcome.frames, None)
            if logger is not None and cfg.log_trace and len(outcome.trace):
                logger.submit_trace(outcome.trace)
        metrics = summarize(cfg, outcome, conn)
    finally:
        if conn is not None:
            conn.close()
        if logger is not None:
            logger.close()
    if cfg.out_dir is not None:
        (cfg.out_dir / "metrics.json").write_text(json.dumps(metrics, indent=2) + "\n", encoding="utf-8")
    return RunResult(metrics=metrics, outcome=outcome, mcap_path=mcap_path)


def summarize(cfg: RunConfig, out: LoopOutcome, conn: TargetConnection) -> dict[str, Any]:
    """Metrics over the metrics window plus run-level facts (end reason, lateness, link counters)."""
    periods = out.periods.all()
    window = periods[out.window_start_period:]
    stats = conn.link_stats()
    link_stats = {"frames_tx": stats.get("frames_tx", 0), "frames_rx": stats.get("frames_rx", 0),
                  "crc_errors": stats.get("crc_errors", 0), "lost": out.lost_commands,
                  "late": out.late_commands}
    if len(window) == 0 or len(out.trace) == 0:
        raise HilError(f"run ended before the metrics window: {out.end_reason}")
    wall_window = out.wall_time_s * len(window) / max(len(periods), 1)
    metrics = compute_run_metrics(window, out.trace, ts_s=cfg.ts_s, pole_pairs=cfg.motor.pole_pairs,
                                  legs=cfg.machine.phases, wall_time_s=wall_window, link_stats=link_stats,
                                  deadline_misses=out.deadline_misses)
    metrics["link"].update({k: v for k, v in stats.items() if k not in metrics["link"]})
    metrics["end_reason"] = out.end_reason
    metrics["safe_state"] = out.safe_state
    metrics["total_periods"] = out.completed_periods
    metrics["total_wall_time_s"] = out.wall_time_s
    metrics["loop_rate_total_hz"] = out.completed_periods / out.wall_time_s if out.wall_time_s else None
    metrics["controller"] = cfg.controller
    metrics["scenario"] = cfg.scenario.name
    metrics["speed_ref_rpm"] = cfg.scenario.speed_rpm
    metrics["load_nm"] = cfg.scenario.load_nm
    metrics["mode"] = cfg.mode
    metrics["link_spec"] = cfg.link
    if cfg.mode == "realtime" and out.lateness_ns:
        lat = np.asarray(out.lateness_ns, dtype=np.float64) / 1e3
        metrics["lateness_us"] = {"median": float(np.median(lat)), "p99": float(np.percentile(lat, 99)),
                                  "max": float(lat.max())}
    speed_err = metrics.get("speed_mean_rpm", math.nan) - cfg.scenario.speed_rpm
    metrics["speed_error_pct"] = 100.0 * speed_err / cfg.scenario.speed_rpm if cfg.scenario.speed_rpm else None
    metrics["candidate_miss_rate"] = (out.candidate_misses / out.candidate_checked
                                      if out.candidate_checked else None)
    return metrics
