"""`hil bench plant`: plant periods per second, and the comparison with gym-electric-motor."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from pmsm_hil.app.cli.parsing import positive_int
from pmsm_hil.hil.atomic_write import write_text_atomic


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `plant` under `hil bench`."""
    p = subparsers.add_parser(
        "plant", help="plant periods per second (and the ratio against gym-electric-motor)",
        description="""Time the plant (niu2020-ipmsm, 1500 rpm dyno, Ts = 100 µs) for single-vector and
                       three-sub-interval periods with the 2 µs trace on and off; when gym-electric-motor is installed,
                       time its PMSM step and compare its currents with ours.""")
    p.add_argument("--periods", type=positive_int, default=20_000, metavar="N",
                   help="periods per repeat (default %(default)s)")
    p.add_argument("--repeats", type=positive_int, default=5, metavar="R",
                   help="repeats, median reported (default %(default)s)")
    p.add_argument("--accuracy-periods", type=positive_int, default=2000, metavar="N",
                   help="random single-vector periods for the GEM accuracy comparison (default %(default)s)")
    p.add_argument("--no-gem", action="store_true", help="skip gym-electric-motor even if installed")
    p.add_argument("--json", type=Path, metavar="FILE", help="also write the figures as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute `hil bench plant`."""
    from pmsm_hil.app.bench.plant_bench import format_result, run_plant_bench  # numpy, the plant: when it runs

    result = run_plant_bench(args.periods, args.repeats, accuracy_periods=args.accuracy_periods,
                             include_gem=not args.no_gem)
    for line in format_result(result):
        print(line)
    if args.json is not None:
        write_text_atomic(args.json, json.dumps(result.to_dict(), indent=2) + "\n", option="--json")
        print(f"figures written to {args.json}")
    return 0
