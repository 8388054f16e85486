"""`hil bench memory`: peak RSS and wall time of `hil run` for several simulated durations."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from pmsm_hil.app.bench.memory import format_points, measure, to_dict
from pmsm_hil.app.cli.parsing import positive_float
from pmsm_hil.hil.atomic_write import write_text_atomic


def _durations(text: str) -> list[float]:
    parse = positive_float("--durations")
    return [parse(part) for part in text.split(",")]


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `memory` under `hil bench`."""
    p = subparsers.add_parser(
        "memory", help="peak RSS and wall time of hil run against its simulated duration",
        description="""Run `hil run` (default controller and motor, lockstep, in-process target) for each duration in a
                       fresh interpreter and print its peak resident memory (host process and MCAP logger process) and
                       wall time per simulated second. Goal: a 600 s run under 500 MB, wall time linear in duration
                       within 10 %; --mode realtime: the longest run's RSS within 10 % of the shortest's.""")
    p.add_argument("--durations", type=_durations, default=[10.0, 60.0, 600.0], metavar="S,S,...",
                   help="simulated durations [s] (default 10,60,600)")
    p.add_argument("--no-log", action="store_true", help="runs without the MCAP log (default: logged)")
    p.add_argument("--log-trace", action="store_true", help="also log the 2 µs plant trace")
    p.add_argument("--controller", default="mpcc", metavar="NAME", help="controller (default %(default)s)")
    p.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep",
                   help="lockstep (default) or realtime: wall-clock paced runs (a 600 s run takes 600 s); the goal "
                        "there is the longest run's RSS within 10 %% of the shortest's, with the growth "
                        "rate in MB/min")
    p.add_argument("--json", type=Path, metavar="FILE", help="also write the figures as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute `hil bench memory`."""
    points = []
    for duration in args.durations:
        print(f"running {duration:g} s ...", file=sys.stderr, flush=True)
        points.append(measure(duration, log=not args.no_log, log_trace=args.log_trace, controller=args.controller,
                              mode=args.mode))
    for line in format_points(points, realtime=args.mode == "realtime"):
        print(line)
    if args.json is not None:
        write_text_atomic(args.json, json.dumps(to_dict(points), indent=2) + "\n", option="--json")
        print(f"figures written to {args.json}")
    return 0
