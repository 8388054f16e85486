"""The figures of `hil bench realtime`: real-time lateness of the period loop at each control period, in process
and over UDP to the native (C) target in its own process, beside the floor a bare C busy loop measures on the
same CPU and priority in the same run, and how far above that floor the loop is.

Per (Ts, link, loop): lateness p50 / p99 / p99.99 [µs] (medians over the repeats), the maximum over all runs
[µs], overruns per 100k periods (over all runs), deadline misses, periods, and the C loop's lateness histogram
(1 µs bins, counted in C per period, summed over the runs) for the OSADL-style report (latency_report.py).
"""

from __future__ import annotations

import math
import os
import statistics
import time
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from pmsm_hil.hil.runner.core_link import NativeLoopUnavailableError, native_lib
from pmsm_hil.hil.runner.loop_config import SPIN_NS_FIFO, rt_throttled
from pmsm_hil.hil.runner.pm_qos import LEAVE, cpu_latency_held
from pmsm_hil.hil.runner.reference_loop import reference_loop
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.target_setup import realtime_target_may_spin
from pmsm_hil.hil.runner.wire import default_spin_ns

#: where the target runs: in process (the C target core called by the loop) or in its own process over UDP
#: loopback (`--target spawn`: the native C target, `hil target --native`)
LINKS = ("inproc", "udp")
#: a real-time run over a link goes on through missed Commands: the bench counts them, it does not stop at one
_NEVER = 1_000_000_000
#: the goal on a quiet machine: lateness p99 at most this [µs] ...
GOAL_P99_US = 2.0
#: ... and overruns at most this many times the floor's gaps of the same run
GOAL_FLOOR_RATIO = 2.0


def loops(link: str) -> tuple[str, ...]:
    """The loops measured on `link`: the C loop, and in process the Python reference loop beside it where the
    test suite provides it (tests/oracle; not part of the product)."""
    return ("python", "native") if link == "inproc" and reference_loop() is not None else ("native",)


def config(link: str, loop: str, duration: float, ts: float, rt_priority: int, cpu: int | None,
           cpu_dma_latency_us: int | None = None) -> RunConfig:
    """The measured run: niu2020 IPMSM, MPCC, steady scenario without settling, `duration` s of real time; over
    UDP a missed Command applies the zero vector (`--miss-policy zero`): the bench measures timing, and with the
    last command held a burst of misses ends the series in an overcurrent trip (docs/benchmarks.md)."""
    values: dict[str, Any] = {"motor": "niu2020-ipmsm", "controller": "mpcc", "settle": 0.0, "duration": duration,
                              "ts": ts, "mode": "realtime", "loop": loop, "rt_priority": rt_priority, "cpu": cpu,
                              "cpu_dma_latency": cpu_dma_latency_us, "no_log": True}
    if link == "udp":  # a burst of misses must not end a timing series with an overcurrent trip (`hold` did here)
        values.update(link="udp", target="spawn", tolerate=_NEVER, watchdog_periods=_NEVER, miss_policy="zero")
    return RunConfig.from_options(values, {key: "hil bench realtime" for key in ("motor", "controller", "settle",
                                                                                 "mode", "no_log", "link", "target",
                                                                                 "tolerate", "watchdog_periods",
                                                                                 "miss_policy")})


def _summary(metrics: list[dict[str, Any]], lateness: list[Any], hist: np.ndarray | None) -> dict[str, Any]:
    periods = sum(int(m["total_periods"]) for m in metrics)
    overruns = sum(int(m["overruns"]) for m in metrics)
    return {
        "lateness_p50_us": statistics.median(q.median() for q in lateness),
        "lateness_p99_us": statistics.median(q.percentile(99.0) for q in lateness),
        "lateness_p9999_us": statistics.median(q.percentile(99.99) for q in lateness),
        "lateness_max_us": max(q.maximum() for q in lateness),
        "overruns_per_100k": 1e5 * overruns / periods if periods else None,
        "overruns": overruns,
        "deadline_misses": sum(int(m["deadline_misses"]) for m in metrics),
        "periods": periods,
        "warnings": metrics[-1]["warnings"],
        "cpu_dma_latency_us": metrics[-1].get("cpu_dma_latency_us"),
        "histogram_1us": None if hist is None else [int(c) for c in hist],
    }


def measure_link(link: str, duration: float, ts: float, repeats: int, rt_priority: int = 0, cpu: int | None = None,
                 log_dir: Path | None = None, loads: list[float] | None = None,
                 progress: Callable[[str], None] = lambda _m: None, cpu_dma_latency_us: int | None = None
                 ) -> dict[str, Any]:
    """Per loop on `link`: the figures of the module docstring; the loops run alternately so both see the same
    load. `loads` collects the 1-min load average after each run. A run that fails is an `error` entry."""
    names = loops(link)
    metrics: dict[str, list[dict[str, Any]]] = {n: [] for n in names}
    lateness: dict[str, list[Any]] = {n: [] for n in names}
    hists: dict[str, np.ndarray | None] = {n: None for n in names}
    errors: dict[str, str] = {}
    for i in range(max(repeats, 1)):
        for loop in names:
            if loop in errors:
                continue
            progress(f"Ts = {ts * 1e6:g} µs, {link}, {loop} loop, run {i + 1} of {max(repeats, 1)} ({duration:g} s)")
            cfg = config(link, loop, duration, ts, rt_priority, cpu, cpu_dma_latency_us)
            if log_dir is not None:
                cfg = replace(cfg, out_dir=log_dir / f"{link}-{loop}-{round(ts * 1e9)}ns-{i}")
            try:
                res = run_closed_loop(cfg)
            except Exception as exc:  # the bench goes on: one refused link must not hide the others
                errors[loop] = str(exc)
                continue
            metrics[loop].append(res.metrics)
            lateness[loop].append(res.outcome.lateness_us)
            h = res.outcome.lateness_hist_1us
            if h is not None:
                prev = hists[loop]
                hists[loop] = h.copy() if prev is None else prev + h
            if loads is not None:
                loads.append(os.getloadavg()[0])
    out: dict[str, Any] = {}
    for loop in names:
        if metrics[loop]:
            out[loop] = _summary(metrics[loop], lateness[loop], hists[loop])
        else:
            out[loop] = {"error": errors.get(loop, "no run")}
    return out


def gap_floor(duration: float, ts: float, rt_priority: int, cpu: int | None) -> dict[str, Any] | None:
    """What a bare C busy loop on the same CPU and priority sees for `duration` s: gaps between two clock reads
    longer than Ts/2 (the default overrun threshold) per 100k periods, longer than 10 µs, the longest, the
    share of the probe's time lost in them (its wall time: a stall may outlast `duration`) and every gap per
    1 µs bin (`histogram_1us`, the last open-ended) — the floor under any loop's lateness here (None without the
    native extension)."""
    try:
        ffi, lib = native_lib()
    except NativeLoopUnavailableError:
        return None
    probe = ffi.new("nl_gap_probe_t *")
    t0 = time.monotonic_ns()
    refused = int(lib.nl_gap_probe(round(duration * 1e9), round(ts * 1e9 / 2), -1 if cpu is None else cpu,
                                   rt_priority, probe))
    elapsed_ns = max(time.monotonic_ns() - t0, 1)  # ≥ duration: a stall can outlast the probe's own end
    periods = duration / ts
    return {"gaps_over_threshold_per_100k": 1e5 * int(probe.gaps) / periods, "gaps_over_10us": int(probe.gaps_10us),
            "max_gap_us": int(probe.max_gap_ns) / 1e3, "lost_pct": 100.0 * int(probe.lost_ns) / elapsed_ns,
            "refused_errno": refused, "histogram_1us": [int(c) for c in probe.hist]}


def paced_udp_floor(duration: float, ts: float, rt_priority: int, cpu: int | None) -> dict[str, Any] | None:
    """The floor under the deadline misses of the `udp` runs (src/pmsm_hil/hil/runner/c/links/link_floor.c
    `nl_udp_paced_floor`): a bare C exchange between two processes paced at Ts for `duration` s, this end on the loop's
    CPU and priority, the echo at the same priority waiting for each datagram as the run's native target does (blocking
    on fewer than three CPUs, else spinning): replies that had not come by the next period start (`late`, per 100k and
    %), the median and longest round trip [µs] (None without the native extension, or when it failed)."""
    try:
        ffi, lib = native_lib()
    except NativeLoopUnavailableError:
        return None
    out = ffi.new("nl_udp_paced_floor_t *")
    echo_spin_ns = default_spin_ns() if realtime_target_may_spin() else 0
    err = int(lib.nl_udp_paced_floor(max(round(duration / ts), 1), round(ts * 1e9), -1 if cpu is None else cpu,
                                     rt_priority, echo_spin_ns, out))
    periods = int(out.periods)
    if err != 0 or periods == 0:
        return None
    late = int(out.late)
    return {"periods": periods, "late": late, "late_per_100k": 1e5 * late / periods, "late_pct": 100.0 * late / periods,
            "median_us": int(out.median_ns) / 1e3, "max_us": int(out.max_ns) / 1e3, "echo_spin_us": echo_spin_ns / 1e3}


def floor_ratio(loop_per_100k: float | None, floor_per_100k: float) -> float | None:
    """How far above the floor the loop's overruns are (loop / floor, per 100k periods, same run): 1.0 when both
    are 0, inf when only the floor is 0; None without loop figures."""
    if loop_per_100k is None:
        return None
    if floor_per_100k == 0.0:
        return 1.0 if loop_per_100k == 0.0 else math.inf
    return loop_per_100k / floor_per_100k


def verdict(figures: dict[str, Any], floor: dict[str, Any] | None) -> dict[str, Any]:
    """The real-time goal for one loop's figures: lateness p99 ≤ 2 µs and overruns ≤ 2× the floor of the same run."""
    ratio = None if floor is None else floor_ratio(figures.get("overruns_per_100k"),
                                                   floor["gaps_over_threshold_per_100k"])
    p99 = figures.get("lateness_p99_us")
    return {"floor_ratio": ratio, "p99_ok": p99 is not None and p99 <= GOAL_P99_US,
            "floor_ok": ratio is not None and ratio <= GOAL_FLOOR_RATIO}


def measure(ts_list: list[float], links: list[str], duration: float, repeats: int, rt_priority: int = 0,
            cpu: int | None = None, log_dir: Path | None = None,
            progress: Callable[[str], None] = lambda _m: None, cpu_dma_latency_us: int | None = None
            ) -> dict[str, Any]:
    """Every (Ts, link): the loops' figures, the floor of the same run (measured after the loops, for the same
    duration), the ratio to it and the goal; the load average before, after each run and at the end. The CPUs'
    wake-up latency: as `hil run` holds it (None: 0 while a run's target is in another process; each link's
    `cpu_dma_latency_us` says what its runs held), or held at `cpu_dma_latency_us` (pm_qos.py; -1: left) for the
    loops and the floors."""
    with cpu_latency_held(LEAVE if cpu_dma_latency_us is None else cpu_dma_latency_us) as pm_qos:
        out = _measure(ts_list, links, duration, repeats, rt_priority, cpu, log_dir, progress, cpu_dma_latency_us)
    out["cpu_dma_latency_us"], out["cpu_dma_latency_refused"] = pm_qos.held_us, pm_qos.refused
    return out


def _measure(ts_list: list[float], links: list[str], duration: float, repeats: int, rt_priority: int,
             cpu: int | None, log_dir: Path | None, progress: Callable[[str], None],
             cpu_dma_latency_us: int | None) -> dict[str, Any]:
    loads: list[float] = [os.getloadavg()[0]]
    out: dict[str, Any] = {"duration_s": duration, "repeats": repeats, "rt_priority": rt_priority, "cpu": cpu,
                           "rt_throttled": rt_throttled(), "points": []}
    for ts in ts_list:
        point: dict[str, Any] = {"ts_s": ts, "spins_whole_period": bool(rt_priority) and rt_throttled()
                                 and ts * 1e9 <= SPIN_NS_FIFO}
        for link in links:
            point[link] = measure_link(link, duration, ts, repeats, rt_priority, cpu, log_dir, loads, progress,
                                       cpu_dma_latency_us)
        progress(f"Ts = {ts * 1e6:g} µs, floor: a bare C busy loop ({duration:g} s)")
        floor = gap_floor(duration, ts, rt_priority, cpu)
        point["floor"] = floor
        if "udp" in links:
            progress(f"Ts = {ts * 1e6:g} µs, miss floor: a bare C UDP exchange paced at Ts ({duration:g} s)")
            with cpu_latency_held(0 if cpu_dma_latency_us is None else LEAVE):  # as the udp runs held it
                point["udp_miss_floor"] = paced_udp_floor(duration, ts, rt_priority, cpu)
        for link in links:
            for figures in point[link].values():
                if "error" not in figures:
                    figures.update(verdict(figures, floor))
                    miss_floor = point.get("udp_miss_floor") if link == "udp" else None
                    figures["misses_per_100k"] = 1e5 * figures["deadline_misses"] / max(figures["periods"], 1)
                    figures["miss_floor_ratio"] = (None if miss_floor is None else
                                                   floor_ratio(figures["misses_per_100k"], miss_floor["late_per_100k"]))
        out["points"].append(point)
    loads.append(os.getloadavg()[0])
    out["load_average_1min"] = {"min": min(loads), "max": max(loads), "end": os.getloadavg()}
    return out
