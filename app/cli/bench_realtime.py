"""`hil bench realtime`: real-time lateness of the Python and the native (C) period loop side by side —
lateness p50 / p99 / max [µs] and overruns per 100k periods, in-process target, medians of repeats run
alternately, with the machine's load average (this machine is shared: figures are noisy)."""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

from pmsm_hil.app.cli.parsing import non_negative_int, positive_float
from pmsm_hil.hil.atomic_write import write_text_atomic
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.native_config import rt_throttled
from pmsm_hil.hil.runner.native_link import NativeLoopUnavailableError, native_lib
from pmsm_hil.hil.runner.reference_loop import reference_loop
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario

LOOPS = ("python", "native")


def loops() -> tuple[str, ...]:
    """The loops to measure: the C loop, and the Python reference loop beside it where the test suite provides it
    (tests/oracle; not part of the product)."""
    return LOOPS if reference_loop() is not None else ("native",)


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `hil bench realtime`."""
    p = subparsers.add_parser("realtime", help="real-time lateness and overruns: Python vs native loop")
    p.add_argument("--duration", type=positive_float("--duration"), default=1.0,
                   help="seconds of real time per run (default 1.0)")
    p.add_argument("--ts", type=positive_float("--ts"), default=100e-6, help="control period [s] (default 100e-6)")
    p.add_argument("--repeats", type=non_negative_int("--repeats"), default=3, help="runs per loop (median)")
    p.add_argument("--rt-priority", type=non_negative_int("--rt-priority"), default=0,
                   help="SCHED_FIFO priority of the native loop thread (default 0: none)")
    p.add_argument("--cpu", type=non_negative_int("--cpu"), help="pin the native loop thread to this CPU")
    p.add_argument("--log", action="store_true", help="log each run to MCAP as `hil run` does (default off)")
    p.add_argument("--json", type=Path, help="write the figures as JSON")
    p.set_defaults(func=run)


def _config(loop: str, duration: float, ts: float, rt_priority: int, cpu: int | None) -> RunConfig:
    scenario = load_scenario("steady").with_overrides(settle_s=0.0, duration_s=duration)
    return RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=scenario, controller="mpcc", ts_s=ts,
                     mode="realtime", loop=loop, rt_priority=rt_priority, cpu=cpu)


def measure(duration: float, ts: float, repeats: int, rt_priority: int = 0, cpu: int | None = None,
            log_dir: Path | None = None) -> dict[str, Any]:
    """Per loop: median lateness p50 / p99 / max [µs] over the runs, overruns per 100k periods over all runs,
    deadline misses, periods, and the warnings of the last run (e.g. a refused priority)."""
    runs: dict[str, list[dict[str, Any]]] = {loop: [] for loop in loops()}
    for i in range(max(repeats, 1)):
        for loop in runs:  # alternately: both loops see the same machine load
            cfg = _config(loop, duration, ts, rt_priority, cpu)
            if log_dir is not None:
                cfg = replace(cfg, out_dir=log_dir / f"{loop}{i}")
            runs[loop].append(run_closed_loop(cfg).metrics)
    out: dict[str, Any] = {"duration_s": duration, "ts_s": ts, "repeats": repeats}
    for loop, metrics in runs.items():
        periods = sum(int(m["total_periods"]) for m in metrics)
        overruns = sum(int(m["overruns"]) for m in metrics)
        out[loop] = {
            "lateness_p50_us": statistics.median(m["lateness_us"]["median"] for m in metrics),
            "lateness_p99_us": statistics.median(m["lateness_us"]["p99"] for m in metrics),
            "lateness_max_us": statistics.median(m["lateness_us"]["max"] for m in metrics),
            "overruns_per_100k": 1e5 * overruns / periods if periods else None,
            "overruns": overruns,
            "deadline_misses": sum(int(m["deadline_misses"]) for m in metrics),
            "periods": periods,
            "warnings": metrics[-1]["warnings"],
        }
    out["load_average"] = os.getloadavg()
    out["rt_throttled"] = rt_throttled()
    out["floor"] = gap_floor(duration, ts, rt_priority, cpu)
    return out


def gap_floor(duration: float, ts: float, rt_priority: int, cpu: int | None) -> dict[str, Any] | None:
    """What a bare C busy loop on the same CPU and priority sees for `duration` s: gaps between two clock reads
    longer than Ts/2 (the default overrun threshold) per 100k periods, longer than 10 µs, the longest, and the
    share of time lost in them — the floor under any loop's lateness here (None without the native extension)."""
    try:
        ffi, lib = native_lib()
    except NativeLoopUnavailableError:
        return None
    probe = ffi.new("nl_gap_probe_t *")
    refused = int(lib.nl_gap_probe(round(duration * 1e9), round(ts * 1e9 / 2), -1 if cpu is None else cpu,
                                   rt_priority, probe))
    periods = duration / ts
    return {"gaps_over_threshold_per_100k": 1e5 * int(probe.gaps) / periods, "gaps_over_10us": int(probe.gaps_10us),
            "max_gap_us": int(probe.max_gap_ns) / 1e3, "lost_pct": 100.0 * int(probe.lost_ns) / (duration * 1e9),
            "refused_errno": refused}


def run(args: argparse.Namespace) -> int:
    """Execute `hil bench realtime`."""
    print(f"bench realtime: {args.repeats} × {args.duration:g} s per loop at Ts = {args.ts * 1e6:g} µs ...",
          file=sys.stderr, flush=True)
    figures = measure(args.duration, args.ts, args.repeats, args.rt_priority, args.cpu,
                      Path("runs") / "bench-realtime" if args.log else None)
    load = figures["load_average"]
    print(f"real time, in-process target, niu2020 IPMSM, MPCC, Ts = {args.ts * 1e6:g} µs, {args.repeats} × "
          f"{args.duration:g} s per loop (medians); load average {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f}")
    print(f"  {'loop':<8} {'p50 µs':>9} {'p99 µs':>9} {'max µs':>10} {'overruns/100k':>14} {'misses':>7} "
          f"{'periods':>8}")
    for loop in (name for name in LOOPS if name in figures):
        f = figures[loop]
        per = f["overruns_per_100k"]
        print(f"  {loop:<8} {f['lateness_p50_us']:>9.2f} {f['lateness_p99_us']:>9.2f} {f['lateness_max_us']:>10.1f} "
              f"{per if per is None else format(per, '14.1f'):>14} {f['deadline_misses']:>7} {f['periods']:>8}")
        for line in f["warnings"]:
            print(f"    {loop}: {line}")
    floor = figures["floor"]
    if floor is not None:
        print(f"  floor: a bare C busy loop ({args.duration:g} s, same CPU and priority) saw "
              f"{floor['gaps_over_threshold_per_100k']:.1f} gaps > Ts/2 per 100k periods, {floor['gaps_over_10us']} "
              f"gaps > 10 µs, the longest {floor['max_gap_us']:.1f} µs, {floor['lost_pct']:.2f} % of the time lost "
              f"(interrupts, other tasks, the hypervisor: no loop here can do better)")
    if args.rt_priority:
        if figures["rt_throttled"]:
            print("  note: the kernel throttles real-time tasks (kernel.sched_rt_runtime_us ≥ 0), so the SCHED_FIFO "
                  "loop sleeps until 70 µs before each period start and a late wake-up shows as lateness; "
                  "`sysctl -w kernel.sched_rt_runtime_us=-1` lets it busy-wait (docs/benchmarks.md)")
        else:
            print("  real-time throttling is off (kernel.sched_rt_runtime_us = -1): the SCHED_FIFO loop busy-waits "
                  "to each period start")
    if args.json is not None:
        write_text_atomic(args.json, json.dumps(figures, indent=2) + "\n", option="--json")
    return 0
