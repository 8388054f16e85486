"""Orchestrates one closed-loop run: target, plant, logger, loop, metrics and outputs."""

from __future__ import annotations

import contextlib
import json
import math
import signal
import subprocess
from collections.abc import Callable, Iterator, Mapping
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass
from pathlib import Path
from types import FrameType
from typing import Any

import numpy as np

from pmsm_hil.hil.atomic_write import write_text_atomic
from pmsm_hil.hil.metrics.errors import MetricsWindowError
from pmsm_hil.hil.metrics.lateness import lateness_histogram
from pmsm_hil.hil.metrics.registry import METRICS, WINDOW
from pmsm_hil.hil.metrics.streaming import HARMONIC_KEYS
from pmsm_hil.hil.runner.block_sink import RunSink
from pmsm_hil.hil.runner.budget_check import check_realtime_budget
from pmsm_hil.hil.runner.contract import RULES, EndCode
from pmsm_hil.hil.runner.link_losses import attribute as attribute_losses
from pmsm_hil.hil.runner.link_losses import target_link_stats
from pmsm_hil.hil.runner.loop_outcome import LoopOutcome
from pmsm_hil.hil.runner.loop_run import (
    connect_loop_target,
    pm_qos_latency_us,
    python_loop_reason,
    realtime_warnings,
    run_native,
)
from pmsm_hil.hil.runner.pm_qos import cpu_latency_held
from pmsm_hil.hil.runner.recorder import frame_records, period_records
from pmsm_hil.hil.runner.reference_loop import require_reference_loop
from pmsm_hil.hil.runner.run_config import RunConfig, controller_id
from pmsm_hil.hil.runner.run_dir_lock import run_dir_lock
from pmsm_hil.hil.runner.run_limits import check_run_limits
from pmsm_hil.hil.runner.run_metadata import run_metadata, tap_setup_frames
from pmsm_hil.hil.runner.safe_stop import SAFE_STOP_TIMEOUT_S, disable_and_confirm, settle_ending
from pmsm_hil.hil.runner.setpoint_hold import setpoint_verdict
from pmsm_hil.hil.runner.sil_watch import InterruptGuard, describe_exit, isolated_config
from pmsm_hil.hil.runner.stop_request import deferred_interrupts
from pmsm_hil.hil.runner.target_client import BusStarvedError, DutViolationError, TargetError
from pmsm_hil.hil.runner.target_console import MAX_LINES
from pmsm_hil.hil.runner.target_setup import TargetConnection, connect_target
from pmsm_hil.protocol.errors import LinkError
from pmsm_hil.protocol.links.kernel_drops import link_kernel_drops
from pmsm_hil.protocol.links.spec import redact_spec
from pmsm_hil.protocol.links.wire_core import link_end, link_socket_drops


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
    (cfg.out_dir / "metrics.json").unlink(missing_ok=True)  # never a new log beside an old run's metrics
    path = cfg.out_dir / "run.mcap"
    return RunLogger(path, metadata=run_metadata(cfg), trace_dtype=cfg.machine.layout.trace_dtype,
                     ring_bytes=logger_ring_bytes(cfg)), path


#: what a period can put into the logger's ring at most, besides its trace rows [B]: the period record (234 B)
#: and 16 frame records (83 B each; a period has 2-6 frames), rounded up
#: wall time [s] a link error during the configuration waits for the target's process to be seen ended
TARGET_END_WAIT_S = 0.5
_RING_BYTES_PER_PERIOD = 2048
_RING_MIN_BYTES = 4 * 1024 * 1024


def logger_ring_bytes(cfg: RunConfig) -> int:
    """The logger's ring for this run [B]: twice what the whole run can log (its periods, frames and, with
    `log_trace`, trace rows), at least 4 MiB (set-up frames, console lines), at most the logger's default
    64 MiB. A ring that holds the whole run never makes the loop wait for the logger, as the default does not for
    a short run; making (its pages are touched before the loop) and dropping 64 MiB cost ~0.15 CPU-s a run."""
    from pmsm_hil.hil.runlog.logger import DEFAULT_RING_BYTES

    periods = cfg.scenario.total_s / cfg.ts_s + 1
    per_period = _RING_BYTES_PER_PERIOD
    if cfg.log_trace:
        per_period += cfg.machine.layout.trace_dtype.itemsize * (math.ceil(cfg.ts_s / cfg.trace_dt_s) + 1)
    wanted = 2 * periods * per_period
    if not math.isfinite(wanted):
        return DEFAULT_RING_BYTES
    return int(min(DEFAULT_RING_BYTES, max(_RING_MIN_BYTES, math.ceil(wanted / 4096) * 4096)))


def run_closed_loop(cfg: RunConfig, *, silent_after: int | None = None,
                    live: Callable[[np.ndarray], None] | None = None,
                    phase: Callable[[str], None] | None = None,
                    counter: Callable[[Callable[[], int]], None] | None = None) -> RunResult:
    """Run the scenario against the target named by cfg.link/cfg.target; returns metrics and outcome.

    Every ending after the target is configured (completed, DUT violation, safety stop, Ctrl-C/SIGTERM,
    internal error) stops safely (disabling Setpoint sent), logs every period up to the last and writes
    metrics.json with `end_reason`, `end_period` and `end_code` (`EndCode`; the exception of an internal error
    is `outcome.error`). A target that breaks the contract while being configured (ConfigAck missing or echoing
    another value) ends the run with `end_code` 4 and no periods.
    `live`: optional consumer of each PERIOD_DTYPE block (~1000 periods), e.g. the live dashboard; `phase`: told
    when the run turns to `configuring target`, `running` and `writing outputs` (`hil run`'s status line);
    `counter`: given, as the loop starts, a function returning the periods it has run so far (read live)."""
    cfg = isolated_config(cfg)  # a SIL target in its own process: its link and --step-timeout
    cid = controller_id(cfg.controller)
    check_run_limits(cfg)
    if cfg.mode == "realtime":
        check_realtime_budget(cfg.link, cfg.ts_s, cfg.machine.phases)
    python_reason = python_loop_reason(cfg)
    with ExitStack() as held:
        if cfg.out_dir is not None:  # one run at a time in a run directory (the CLI holds it already)
            held.enter_context(run_dir_lock(cfg.out_dir, option="out_dir"))
        return _run_locked(cfg, cid, python_reason, silent_after, live, phase or _no_phase, counter)


def _no_phase(name: str) -> None:
    """No one follows the run's phases."""


def run_from_options(values: Mapping[str, Any], sources: Mapping[str, str] | None = None, *,
                     live: Callable[[np.ndarray], None] | None = None) -> RunResult:
    """One run of run-option values by key (`RunConfig.from_options`, the path of `hil run`, sweeps and the pytest
    plugin: the same defaults, checks and errors naming each value's source), e.g.
    `run_from_options({"controller": "foc", "speed": 900, "no_log": True})`."""
    return run_closed_loop(RunConfig.from_options(values, sources), live=live)


def _configure(conn: TargetConnection, cfg: RunConfig) -> None:
    """Write the target's parameters. A link error while the target's process has ended is that process's end (a
    resend can meet the closed socket before the client's pump sees the death): a DutViolationError the ending
    (`conn.ending`) then names as the crash."""
    try:
        conn.client.configure(cfg.target_parameters())
    except LinkError as exc:
        proc = conn.process
        if proc is None:
            raise
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(TARGET_END_WAIT_S)
        if proc.poll() is None:
            raise
        raise DutViolationError(f"the target process ended ({describe_exit(proc.returncode)}): {exc}") from exc


def _run_locked(cfg: RunConfig, cid: int, python_reason: str | None, silent_after: int | None,
                live: Callable[[np.ndarray], None] | None, phase: Callable[[str], None],
                counter: Callable[[Callable[[], int]], None] | None) -> RunResult:
    logger, mcap_path = _open_logger(cfg)
    conn: TargetConnection | None = None
    outcome: LoopOutcome | None = None
    sink = RunSink(cfg, logger, live)
    with ExitStack() as signals:
        try:
            signals.enter_context(_terminate_as_interrupt())
            conn, python_reason = connect_loop_target(
                cfg, python_reason, lambda: connect_target(cfg, silent_after=silent_after), silent_after)
            sink.console, sink.board_records = conn.console, conn.board_records
            pm_qos = signals.enter_context(cpu_latency_held(pm_qos_latency_us(cfg, conn)))
            # from here on Ctrl-C/SIGTERM only ask the loop to end (at a period boundary; at once if the target
            # is still being configured): every period run is logged and counted, the outputs written whole
            guards = [item for item in conn.extra if isinstance(item, InterruptGuard)]
            for guard in guards:  # the deferred stop request takes the signals over from a SIL target's guard
                guard.release_handlers()
            stop = signals.enter_context(deferred_interrupts())
            for guard in guards:
                signals.enter_context(stop.hook(guard.on_stop))
            phase("configuring target")
            try:
                with tap_setup_frames(conn.client, logger):
                    _configure(conn, cfg)
            except (DutViolationError, BusStarvedError) as exc:  # the bus's: a safety stop naming it, not exit 4
                bus = isinstance(exc, BusStarvedError)
                outcome = LoopOutcome(period_records(), frame_records(), np.zeros(0, cfg.machine.layout.trace_dtype),
                                      0, end_reason=f"{exc} while configuring" if bus else
                                      f"DUT contract violation while configuring: {exc}",
                                      end_code=int(EndCode.SAFETY_STOP if bus else EndCode.DUT_VIOLATION),
                                      safe_state=True)
                try:
                    with tap_setup_frames(conn.client, logger):  # the disabling Setpoint is logged too
                        settle_ending(outcome, disable_and_confirm(
                            conn.client, cid, clock=conn.own_time(SAFE_STOP_TIMEOUT_S),
                            stall_limit_s=cfg.host_stall_limit_s))
                except (LinkError, TargetError):  # the target is gone (e.g. a SIL process that crashed)
                    outcome.target_disabled = False
            if outcome is None:
                phase("running")
                if counter is not None:
                    counter(lambda: sink.loop_periods())
                outcome = (require_reference_loop()(cfg, conn, cid, sink) if python_reason
                           else run_native(cfg, conn, cid, sink))
            # e.g. a SIL target process that crashed or hung; not one the run's own stop killed (Ctrl-C/SIGTERM)
            if conn.ending is not None and outcome.end_code != EndCode.INTERRUPTED:
                conn.ending(outcome)
            phase("writing outputs")
            metrics = summarize(cfg, outcome, conn, sink)
            metrics["loop"], metrics["loop_note"] = "python" if python_reason else "native", python_reason
            metrics["warnings"] += realtime_warnings(cfg, conn)
            if cfg.mode == "realtime":
                metrics["cpu_dma_latency_us"] = pm_qos.held_us
                metrics["warnings"] += [w for w in (pm_qos.warning(),) if w is not None]
        finally:
            if conn is not None:
                conn.close()
                with contextlib.suppress(Exception):  # what the target wrote after the last block
                    sink.flush_console()
            if logger is not None:
                logger.close()
        attribute_losses(metrics, target_link_stats(conn) if conn is not None else None)
        outcome.end_reason = metrics["end_reason"]
        if cfg.out_dir is not None:
            write_text_atomic(cfg.out_dir / "metrics.json", json.dumps(metrics, indent=2) + "\n",
                              option="metrics file")
    return RunResult(metrics=metrics, outcome=outcome, mcap_path=mcap_path)


def _window_metrics(cfg: RunConfig, out: LoopOutcome, sink: RunSink, link_stats: dict[str, int]) -> dict[str, Any]:
    """Metrics over the window; every window key null (with the reason) when the run ended before it."""
    window = sink.window
    wall_window = out.wall_time_s * window.periods / max(out.completed_periods, 1)
    if window.periods and window.torque.samples:
        try:
            return window.result(ts_s=cfg.ts_s, pole_pairs=cfg.motor.pole_pairs, legs=cfg.machine.phases,
                                 wall_time_s=wall_window, link_stats=link_stats, deadline_misses=out.deadline_misses,
                                 friction_nms=cfg.motor.b,
                                 inertia_kgm2=cfg.scenario.driven_inertia_kgm2(cfg.motor.j))
        except MetricsWindowError as exc:
            note = str(exc)
    else:
        note = f"run ended before the metrics window ({window.periods} window periods)"
    metrics: dict[str, Any] = {m.key: None for m in METRICS if m.source == WINDOW and m.sub is None}
    metrics.update(periods=window.periods, link=dict(link_stats), deadline_misses=out.deadline_misses,
                   current_thd_note=note, not_applicable={key: note for key in HARMONIC_KEYS})
    metrics.pop("xy_current_rms_a", None)
    return metrics


def _bus_traffic(out: LoopOutcome, conn: TargetConnection) -> dict[str, int | None]:
    """`bus_foreign_frames`, `bus_suspect_frames`: the loop's count, else the set-up's (None: not a shared bus)."""
    client = conn.client
    if not client.shared:
        return {"bus_foreign_frames": None, "bus_suspect_frames": None}
    foreign, suspect = out.bus_foreign_frames, out.bus_suspect_frames
    return {"bus_foreign_frames": client.bus.foreign if foreign is None else foreign,
            "bus_suspect_frames": client.bus.suspect if suspect is None else suspect}


def summarize(cfg: RunConfig, out: LoopOutcome, conn: TargetConnection, sink: RunSink) -> dict[str, Any]:
    """Metrics over the metrics window plus run-level facts (ending, contract findings, lateness, link)."""
    stats = conn.link_stats()
    link_stats = {"frames_tx": stats.get("frames_tx", 0), "frames_rx": stats.get("frames_rx", 0),
                  "crc_errors": stats.get("crc_errors", 0), "lost": out.lost_commands,
                  "late": out.late_commands}
    metrics = _window_metrics(cfg, out, sink, link_stats)
    metrics["link"].update({k: v for k, v in stats.items() if k not in metrics["link"]})
    metrics["link"].update(link_socket_drops(conn.host_link))
    metrics["link"].update(link_kernel_drops(conn.host_link))
    metrics["link_authenticated"] = getattr(link_end(conn.host_link), "authenticated", False) is True
    metrics["end_reason"] = out.end_reason
    metrics["end_code"] = out.end_code
    metrics["end_period"] = out.completed_periods - 1
    metrics["safe_state"] = out.safe_state
    metrics["target_disabled"] = out.target_disabled
    metrics.update(out.safe_stop.metrics() if out.safe_stop is not None else
                   {"safe_stop_confirmed": None, "safe_stop_wait_ms": None, "safe_stop_observed": None})
    metrics["dut_violations"] = out.violation_count
    metrics["dut_violation_list"] = [v.as_dict() for v in out.violations]
    metrics["dut_violations_by_rule"] = {rule: out.violations_by_rule.get(rule, 0) for rule in RULES}
    metrics["tolerate"] = cfg.tolerate
    metrics["link_faults"] = out.link_faults
    metrics["command_wait_max_us"] = out.max_wait_ns / 1e3
    metrics["host_stalls"] = out.host_stalls
    metrics["host_stall_s"] = out.host_stall_s
    metrics["total_periods"] = out.completed_periods
    metrics["total_wall_time_s"] = out.wall_time_s
    metrics["loop_rate_total_hz"] = out.completed_periods / out.wall_time_s if out.wall_time_s else None
    metrics["controller"] = cfg.controller
    metrics["scenario"] = cfg.scenario.name
    metrics["speed_ref_rpm"] = cfg.scenario.speed_rpm
    metrics["load_nm"] = cfg.scenario.load_nm if cfg.load_fmu is None else None
    metrics["load_fmu"] = out.load_fmu
    metrics["mode"] = cfg.mode
    metrics["link_spec"] = redact_spec(cfg.link)  # a key= never reaches metrics.json
    metrics.update(_bus_traffic(out, conn))
    warnings: list[str] = []
    lat = out.lateness_us
    if cfg.mode == "realtime" and lat.n:
        metrics["lateness_us"] = {"median": lat.median(), "p99": lat.percentile(99.0), "max": lat.maximum()}
        metrics["lateness_histogram_us"] = lateness_histogram(lat)
        threshold_us = cfg.overrun_threshold_ns / 1e3
        metrics["overruns"] = out.overruns
        metrics["realtime_sync_us"] = out.realtime_sync_us
        metrics["overrun_threshold_us"] = threshold_us
        if out.overruns or metrics["lateness_us"]["p99"] > threshold_us:
            warnings.append(f"real time: {out.overruns} of {lat.n} periods started more than {threshold_us:g} µs "
                            f"late (lateness p99 {metrics['lateness_us']['p99']:.1f} µs): the host did not keep "
                            f"the period; timing results are not trustworthy")
    speed_mean = metrics.get("speed_mean_rpm")
    speed_err = (speed_mean - cfg.scenario.speed_rpm) if isinstance(speed_mean, float) else math.nan
    metrics["speed_error_pct"] = (100.0 * speed_err / cfg.scenario.speed_rpm
                                  if cfg.scenario.speed_rpm and math.isfinite(speed_err) else None)
    metrics["exec_time_first_us"] = sink.exec_time_first()
    metrics["candidate_miss_rate"] = (out.candidate_misses / out.candidate_checked
                                      if out.candidate_checked else None)
    missed, speed_warning = sink.speed_tail.check() if out.end_code == EndCode.COMPLETED else (None, None)
    metrics["speed_reference_missed"] = missed
    hold, hold_na = setpoint_verdict(sink.speed_tail, cfg.scenario.hold_tolerance_pct,
                                     completed=out.end_code == EndCode.COMPLETED)
    metrics.update(hold)
    not_applicable = metrics.get("not_applicable")
    metrics["not_applicable"] = dict(not_applicable) if isinstance(not_applicable, dict) else {}
    if hold_na is not None:
        metrics["not_applicable"].update({key: hold_na for key in ("setpoint_held", "setpoint_error")})
    if speed_warning is not None:
        warnings.append(speed_warning)
    if out.violation_count and out.end_code != EndCode.DUT_VIOLATION and out.violation_count <= cfg.tolerate:
        warnings.append(f"{out.violation_count} DUT contract violation(s) tolerated (--tolerate {cfg.tolerate}); "
                        f"first: {out.violations[0].message()}")
    if conn.console is not None and conn.console.dropped:
        warnings.append(f"target console: {conn.console.lines} lines, the first {MAX_LINES} logged "
                        f"(/target/console), {conn.console.dropped} dropped")
    if out.host_stalls:
        warnings.append(f"host stall: {out.host_stalls} wait(s) for a Command or the safe stop's confirmation went "
                        f"past its timeout because the host kept the target's process stopped or off the CPUs "
                        f"({out.host_stall_s:.3f} s in all); not counted against the firmware")
    metrics["warnings"] = warnings
    metrics.update(conn.extra_metrics())
    return metrics
