"""`hil replay RUN.mcap`: a recorded run into the Rerun dashboard (viewer, .rrd file or web viewer)."""

from __future__ import annotations

import argparse
from pathlib import Path

from pmsm_hil.app.cli.parsing import positive_float


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `hil replay`."""
    from pmsm_hil.dashboards.cli_live import add_rerun_arguments

    p = subparsers.add_parser("replay", help="replay a recorded run (MCAP) into the Rerun dashboard",
                              description="Any run.mcap of `hil run` into the same blueprint as the live "
                                          "dashboard. Give --rerun, --rerun-save FILE.rrd and/or --rerun-serve.")
    p.add_argument("mcap", type=Path, metavar="RUN.mcap", help="run log written by `hil run`")
    p.add_argument("--vdc", type=positive_float("--vdc"), help="DC-link voltage [V] (default: the run's motor)")
    add_rerun_arguments(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute `hil replay`."""
    from pmsm_hil.dashboards.cli_live import hold_serving, rerun_targets
    from pmsm_hil.dashboards.errors import DashboardError
    from pmsm_hil.dashboards.replay import load_source, replay_to_rerun
    from pmsm_hil.hil.atomic_write import refuse_inputs

    if not args.mcap.is_file():
        raise DashboardError(f"hil replay: RUN.mcap {args.mcap} does not exist or is not a file")
    targets = rerun_targets(args)
    if targets.save is not None:
        refuse_inputs(targets.save, [args.mcap], option="--rerun-save")
    if not targets.any():
        raise DashboardError("hil replay: choose --rerun, --rerun-save FILE.rrd or --rerun-serve")
    source = load_source(args.mcap, vdc=args.vdc)
    rec, url = replay_to_rerun(source, targets)
    print(f"replayed {len(source.periods)} periods of {source.name}")
    if targets.save is not None:
        print(f"rerun: recording saved to {targets.save}")
    if url is not None:
        hold_serving(url)
    rec.disconnect()
    return 0
