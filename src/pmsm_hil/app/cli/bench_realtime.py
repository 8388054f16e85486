"""`hil bench realtime`: real-time lateness of the period loop at each `--ts` — in process and over UDP to the
native (C) target in its own process — lateness p50 / p99 / p99.99 / max [µs] and overruns per 100k periods,
beside the floor a bare C busy loop measures on the same CPU and priority in the same run, with the ratio to it;
`--histogram PREFIX` writes the OSADL-style latency report (CSV and PNG), `--load-cmd` runs a load beside it.
The machine's load average is printed with the figures (a shared machine makes them noisy)."""

from __future__ import annotations

import argparse
import importlib
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pmsm_hil.app.bench.latency_report import write_report
from pmsm_hil.app.bench.load_process import load_beside
from pmsm_hil.app.cli.parsing import non_negative_int, positive_float
from pmsm_hil.app.cli.run_options_cli import add_option
from pmsm_hil.hil.atomic_write import write_text_atomic
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.runner.option_values import coerce
from pmsm_hil.hil.runner.run_options import DEFAULTS, OPTIONS

if TYPE_CHECKING:
    from pmsm_hil.app.bench.realtime import gap_floor

__all__ = ["add_parser", "gap_floor", "run"]


def __getattr__(name: str) -> Any:
    """`gap_floor`, from the measurement's module (the runner: imported when a bench runs, not for its parser)."""
    if name == "gap_floor":
        return importlib.import_module("pmsm_hil.app.bench.realtime").gap_floor
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `hil bench realtime`."""
    p = subparsers.add_parser("realtime", help="real-time lateness and overruns per Ts and link, beside the floor")
    p.add_argument("--duration", type=positive_float("--duration"), default=1.0,
                   help="seconds of real time per run (default 1.0; e.g. 300 for a long-run latency report)")
    add_option(p, OPTIONS["ts"], repeatable=True,
               help="control period [s], repeatable (--ts 50e-6 --ts 25e-6; default 100e-6)")
    p.add_argument("--links", default="inproc,udp",
                   help="comma list of where the target runs: inproc (the C target core in the loop's process), udp "
                        "(the native C target in its own process, UDP loopback) (default inproc,udp)")
    p.add_argument("--repeats", type=non_negative_int("--repeats"), default=3, help="runs per loop (median)")
    add_option(p, OPTIONS["rt_priority"], help="SCHED_FIFO priority 1..99 of the native loop thread and of the "
                                               "spawned native target (default 0: none)")
    add_option(p, OPTIONS["cpu"])
    add_option(p, OPTIONS["cpu_dma_latency"],
               help="hold every CPU's wake-up latency at most US µs during the runs and the floor (PM QoS through "
                    "/dev/cpu_dma_latency, as cyclictest does; needs root; -1: leave the kernel's setting) (default: "
                    "as `hil run`, 0 during the runs whose target is in another process)")
    p.add_argument("--histogram", type=Path, metavar="PATH_PREFIX",
                   help="write the lateness histogram (1 µs bins, every series) as PATH_PREFIX.csv and "
                        "PATH_PREFIX.png (log-scale counts, the maximum of each series, the load)")
    p.add_argument("--load-cmd", metavar="CMD",
                   help="start CMD (e.g. \"stress-ng --cpu 2\") beside the measurement and stop it after; the report "
                        "says how many CPUs it kept busy")
    p.add_argument("--log", action="store_true", help="log each run to MCAP as `hil run` does (default off)")
    p.add_argument("--json", type=Path, help="write the figures as JSON")
    p.set_defaults(func=run)


def _links(text: str) -> list[str]:
    from pmsm_hil.app.bench.realtime import LINKS

    links = [name.strip() for name in text.split(",") if name.strip()]
    bad = [name for name in links if name not in LINKS]
    if bad or not links:
        raise ParameterError(f"--links: {', '.join(bad) or 'empty'}: expected a comma list of {', '.join(LINKS)}")
    return links


def _num(value: float | None, fmt: str) -> str:
    if value is None:
        return "-"
    return "inf" if math.isinf(value) else format(value, fmt)


def _print_point(point: dict[str, Any], links: list[str], duration: float) -> None:
    ts_us = point["ts_s"] * 1e6
    floor = point["floor"]
    print(f"Ts = {ts_us:g} µs ({1e3 / ts_us:g} kHz)")
    print(f"  {'link':<7} {'loop':<7} {'p50 µs':>8} {'p99 µs':>8} {'p99.99 µs':>10} {'max µs':>9} "
          f"{'overruns/100k':>14} {'× floor':>8} {'qos µs':>7} {'misses':>7} {'periods':>9}")
    for link in links:
        for loop, f in point[link].items():
            if "error" in f:
                print(f"  {link:<7} {loop:<7} error: {f['error']}")
                continue
            print(f"  {link:<7} {loop:<7} {f['lateness_p50_us']:>8.2f} {f['lateness_p99_us']:>8.2f} "
                  f"{f['lateness_p9999_us']:>10.2f} {f['lateness_max_us']:>9.1f} "
                  f"{_num(f['overruns_per_100k'], '.1f'):>14} {_num(f['floor_ratio'], '.2f'):>8} "
                  f"{_num(f['cpu_dma_latency_us'], 'd'):>7} {f['deadline_misses']:>7} {f['periods']:>9}")
            for line in f["warnings"]:
                print(f"    ({link}, {loop}) {line}")
    if floor is not None:
        print(f"  floor: a bare C busy loop ({duration:g} s, same CPU and priority) saw "
              f"{floor['gaps_over_threshold_per_100k']:.1f} gaps > Ts/2 per 100k periods, {floor['gaps_over_10us']} "
              f"gaps > 10 µs, the longest {floor['max_gap_us']:.1f} µs, {floor['lost_pct']:.2f} % of the time lost "
              f"(interrupts, other tasks, the hypervisor: no loop here can do better)")
    miss_floor = point.get("udp_miss_floor")
    udp = point.get("udp", {}).get("native", {})
    if miss_floor is not None and "error" not in udp:
        how = "blocking" if miss_floor["echo_spin_us"] == 0 else f"spinning {miss_floor['echo_spin_us']:g} µs"
        print(f"  miss floor (udp): a bare C UDP exchange paced at Ts (the loop's CPU and priority, the echo {how} "
              f"as the target) had {miss_floor['late']} of {miss_floor['periods']} replies after the next period "
              f"start ({miss_floor['late_pct']:.2f} %), round trip median {miss_floor['median_us']:.1f} µs, max "
              f"{miss_floor['max_us']:.1f} µs; the C loop's misses: {udp['misses_per_100k'] / 1e3:.2f} % "
              f"({_num(udp['miss_floor_ratio'], '.2f')}× that)")
    from pmsm_hil.app.bench.realtime import GOAL_FLOOR_RATIO, GOAL_P99_US

    for link in links:
        for loop, f in point[link].items():
            if loop == "native" and "error" not in f:
                ok = f["p99_ok"] and f["floor_ok"]
                print(f"  goal ({link}, C loop): p99 ≤ {GOAL_P99_US:g} µs {'yes' if f['p99_ok'] else 'NO'}, overruns "
                      f"≤ {GOAL_FLOOR_RATIO:g}× the floor {'yes' if f['floor_ok'] else 'NO'}"
                      f"{' — met' if ok else ''}")
    if point["spins_whole_period"]:
        print("  note: at this Ts the SCHED_FIFO loop busy-waits the whole period (it sleeps only until 70 µs before "
              "a period start) while the kernel throttles real-time tasks (kernel.sched_rt_runtime_us ≥ 0): expect "
              "stalls of up to 50 ms per second; `sysctl -w kernel.sched_rt_runtime_us=-1` on a bench PC "
              "(docs/runner.md, qualifying a bench PC)")


def _pm_qos_line(figures: dict[str, Any], asked: int | None) -> str:
    held, refused = figures["cpu_dma_latency_us"], figures["cpu_dma_latency_refused"]
    if asked is None:
        return ("CPU wake-up latency: as `hil run` holds it (PM QoS 0 µs while the target is in another process; "
                "the column 'qos µs' says what each link's runs held, '-' none)")
    if held is not None:
        return f"CPU wake-up latency held at {held} µs (PM QoS, /dev/cpu_dma_latency) for the runs and the floor"
    if refused is not None:
        return (f"CPU wake-up latency NOT held ({refused}): idle CPUs sleep deep, a blocked receive may wake tens "
                "of µs late")
    return "CPU wake-up latency: the kernel's setting (--cpu-dma-latency -1)"


def run(args: argparse.Namespace) -> int:
    """Execute `hil bench realtime`."""
    for key in ("rt_priority", "cpu", "cpu_dma_latency"):  # the run options' own checks, as `hil run` makes them
        if getattr(args, key) is not None:
            coerce(OPTIONS[key], getattr(args, key))
    args.rt_priority = args.rt_priority or DEFAULTS["rt_priority"]
    ts_list = args.ts or [DEFAULTS["ts"]]
    links = _links(args.links)
    def progress(msg: str) -> None:
        print(f"bench realtime: {msg} ...", file=sys.stderr, flush=True)

    from pmsm_hil.app.bench.realtime import measure

    with load_beside(args.load_cmd) as load:
        figures = measure(ts_list, links, args.duration, args.repeats, args.rt_priority, args.cpu,
                          Path("runs") / "bench-realtime" if args.log else None, progress, args.cpu_dma_latency)
    load_line = load.describe() if load is not None else None
    figures["load_cmd"] = None if load is None else {"command": load.command, "cpu_s": load.cpu_s,
                                                     "wall_s": load.wall_s, "exited_early": load.exited_early}
    la = figures["load_average_1min"]
    prio = f"SCHED_FIFO {args.rt_priority}" if args.rt_priority else "normal priority"
    print(f"real time, niu2020 IPMSM, MPCC, C target core, {prio}, {args.repeats} × {args.duration:g} s per loop "
          f"(p50/p99/p99.99: medians over the runs; max: over all runs); load average (1 min) "
          f"{la['min']:.2f}..{la['max']:.2f} during, {la['end'][0]:.2f} / {la['end'][1]:.2f} / {la['end'][2]:.2f} "
          f"at the end")
    if load_line is not None:
        print(f"  {load_line}")
    print(f"  {_pm_qos_line(figures, args.cpu_dma_latency)}")
    for point in figures["points"]:
        _print_point(point, links, args.duration)
    if args.rt_priority and not figures["rt_throttled"]:
        print("real-time throttling is off (kernel.sched_rt_runtime_us = -1): the SCHED_FIFO loop busy-waits to "
              "each period start")
    if args.histogram is not None:
        csv_path, png_path = write_report(args.histogram, figures, load_line)
        print(f"latency histogram: {csv_path}, {png_path}")
    if args.json is not None:
        write_text_atomic(args.json, json.dumps(figures, indent=2) + "\n", option="--json")
    return 0
