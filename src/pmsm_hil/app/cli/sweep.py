"""`hil sweep`: a grid or list of `hil run` runs on a local process pool, Dask or Ray; resumable results
(results.json, results.parquet or .csv), a summary table and an HTML page of plots (docs/sweeps.md)."""

from __future__ import annotations

import argparse
import signal
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from types import FrameType

from pmsm_hil.app.cli.parsing import non_negative_int, positive_int
from pmsm_hil.app.cli.run import EXIT_CODES, add_run_arguments, options_from_args


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `hil sweep`."""
    p = subparsers.add_parser(
        "sweep", help="many runs over a grid or plan of `hil run` choices, on all cores, Dask or Ray",
        description="Runs every point of a grid (or plan file) of `hil run` choices, each --repeat times over "
                    "initial rotor angles, on a local process pool (default, every core), a Dask or a Ray "
                    "cluster. Every run has a stable id (a hash of its configuration); a sweep rerun on the same "
                    "--out skips the runs it finished, so an interrupted sweep resumes. The `hil run` options "
                    "below are the base of every run. Writes OUT/results.json, OUT/results.parquet (else .csv), "
                    "OUT/report.html and prints a summary. Keys: the `hil run` option names without dashes "
                    "(controller, load, speed, duration, ts, motor, scenario, seed, noise, fault, ...), "
                    "set.NAME (--set), param.NAME (--param), theta0 (initial rotor angle, rad). docs/sweeps.md",
        epilog="exit codes: 0 sweep finished (runs that did not complete are rows with their end code; "
               "counted on stderr), 2 usage/config error (nothing ran), 130 interrupted (rerun to resume). "
               "Run end codes: " + EXIT_CODES.removeprefix("exit codes: "))
    g = p.add_argument_group("sweep")
    g.add_argument("--grid", action="append", default=[], metavar="KEY=V1,V2",
                   help="values of one key (repeatable; the points are the product, the last key fastest); "
                        "separate with ';' when a value holds commas (fault=drop=0.1,seed=1;drop=0.2,seed=1)")
    g.add_argument("--plan", type=Path, metavar="FILE.toml|FILE.csv",
                   help="plan file: TOML [grid] KEY = [values] and/or [[runs]] tables, repeat = N; or CSV with a "
                        "header of keys and one run per row (crossed with --grid)")
    g.add_argument("--repeat", type=positive_int, metavar="N",
                   help="runs per point at initial rotor angles theta0 + 2πk/N, seed + k (k = 0..N-1; default 1, "
                        "or the plan's)")
    g.add_argument("--engine", choices=("local", "dask", "ray"), default="local",
                   help="local process pool (default), Dask (a LocalCluster without --address) or Ray (local "
                        "without --address)")
    g.add_argument("--workers", type=non_negative_int("--workers"), metavar="N",
                   help="worker processes of a pool or cluster started here (default: every core; 0: in this "
                        "process)")
    g.add_argument("--address", metavar="ADDR",
                   help="Dask scheduler (tcp://host:8786) or Ray cluster (host:6379, auto) to run on")
    g.add_argument("--out", type=Path, default=Path("sweep"), metavar="DIR",
                   help="output directory; an earlier sweep there is resumed (default %(default)s)")
    g.add_argument("--overwrite", action="store_true", help="discard the results of an earlier sweep in --out")
    g.add_argument("--mcap", action="store_true", help="log every run: STORE/<run id>/run.mcap and metrics.json")
    g.add_argument("--store", type=Path, metavar="DIR",
                   help="where --mcap logs go, a path every worker can see (default OUT/runs; implies --mcap)")
    g.add_argument("--list", action="store_true", help="print the runs (id and configuration) and exit")
    g.add_argument("--quiet", action="store_true", help="no progress line")
    add_run_arguments(p)
    p.set_defaults(func=run)


@contextmanager
def _terminate_as_interrupt() -> Iterator[None]:
    """SIGTERM (a job scheduler, `kill`) stops the sweep like Ctrl-C: results kept, resumable."""
    def handler(signum: int, frame: FrameType | None) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def run(args: argparse.Namespace) -> int:
    """Execute `hil sweep`."""
    from pmsm_hil.app.sweep.configure import build_runs
    from pmsm_hil.app.sweep.engines import open_engine
    from pmsm_hil.app.sweep.execute import run_sweep
    from pmsm_hil.app.sweep.plan import expand, load_plan, parse_grid, swept_keys
    from pmsm_hil.app.sweep.report import summary_lines, write_html
    from pmsm_hil.app.sweep.store import ResultsStore, is_done
    from pmsm_hil.hil.errors import InputFileError, ParameterError

    grid = parse_grid(args.grid)
    plan = load_plan(args.plan) if args.plan is not None else None
    if plan is None and not grid:
        raise ParameterError("hil sweep: give --grid KEY=V1,V2 and/or --plan FILE")
    points = expand(plan.runs if plan else (), [*(plan.grid if plan else ()), *grid])
    repeat = args.repeat or (plan.repeat if plan and plan.repeat else 1)
    runs = build_runs(options_from_args(args, ("run",)), points, repeat, plan=args.plan if plan and not grid else None)
    keys = swept_keys(points) + (["repeat"] if repeat > 1 else [])
    if args.list:
        for r in runs:
            print(f"{r.run_id}  {r.label()}")
        print(f"{len(runs)} runs")
        return 0
    mcap_store = (args.store or args.out / "runs") if (args.mcap or args.store is not None) else None
    if args.out.exists() and not args.out.is_dir():
        raise InputFileError(f"--out {args.out}: exists and is not a directory")
    with _terminate_as_interrupt():
        engine = open_engine(args.engine, workers=args.workers, address=args.address)
        with engine:
            results = ResultsStore(args.out, overwrite=args.overwrite)
            if not args.quiet:
                print(f"hil sweep: {len(runs)} runs on {engine.describe()}", file=sys.stderr)
            if engine.warning:
                print(f"hil: warning: {engine.warning}", file=sys.stderr)
            outcome = run_sweep(runs, engine, results, mcap_store=mcap_store, quiet=args.quiet)
    rows = results.plan_rows([r.run_id for r in runs])
    for line in summary_lines(rows, keys):
        print(line)
    written = list(outcome.written)
    if rows:
        written.append(write_html(results.out / "report.html", rows, keys, title=f"hil sweep: {results.out}"))
    print("written: " + ", ".join(str(p) for p in written))
    not_ok = sum(1 for r in rows if r.get("end_code") != 0)
    if not_ok:
        print(f"hil: {not_ok} of {len(rows)} runs did not complete (end_code and end_reason in "
              f"{results.out / 'results.json'})", file=sys.stderr)
    if outcome.interrupted:
        done = sum(1 for r in rows if is_done(r))
        print(f"hil: interrupted; {done} of {outcome.total} runs done, the same command resumes the sweep",
              file=sys.stderr)
        return 130
    return 0
