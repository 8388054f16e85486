"""`hil mcap export RUN.mcap --format candump|asc|blf|csv -o FILE`: a run's frames as a CAN log."""

from __future__ import annotations

import argparse
from pathlib import Path

#: the --format names: the keys of `pmsm_hil.hil.runlog.can_log.FORMATS` (python-can's writers, imported when a log
#: is exported, not for the parser)
FORMAT_NAMES = ("candump", "asc", "blf", "csv")


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `export` under `hil mcap`."""
    p = subparsers.add_parser("export", help="write a run's /frames as a CAN log (candump, ASC, BLF, CSV)",
                              description="""The frames of a run log at their virtual times (run time, s) through
                                             python-can's log writers: candump -L (can-utils, SavvyCAN), Vector ASC and
                                             BLF (CANalyzer-style tools), python-can CSV. Host-sent frames are written
                                             as Tx, received ones as Rx.""")
    p.add_argument("mcap", type=Path, metavar="RUN.mcap", help="run log written by `hil run`")
    p.add_argument("--format", choices=FORMAT_NAMES, required=True, help="log format")
    p.add_argument("-o", "--output", type=Path, required=True, metavar="FILE", help="the log to write")
    p.add_argument("--overwrite", action="store_true", help="replace an existing -o file (refused without it)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute `hil mcap export`."""
    from pmsm_hil.hil.atomic_write import refuse_existing, refuse_inputs
    from pmsm_hil.hil.runlog.can_log import export_frames

    refuse_inputs(args.output, [args.mcap], option="-o")
    refuse_existing(args.output, overwrite=args.overwrite, option="-o")
    n = export_frames(args.mcap, args.format, args.output)
    print(f"exported {n} frames of {args.mcap} -> {args.output} ({args.format})")
    return 0
