"""`hil report RUN_DIR... -o report.html`: a self-contained HTML page comparing runs."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `hil report`."""
    p = subparsers.add_parser("report", help="HTML report of runs (metrics, whole-run plots, waveforms, spectra, bars)",
                              description="""Reads metrics.json and run.mcap of each `hil run --out` directory and
                                             writes one HTML file with inline SVG figures (no external resources).""")
    p.add_argument("run_dirs", type=Path, nargs="+", metavar="RUN_DIR", help="output directory of `hil run`")
    p.add_argument("-o", "--output", type=Path, default=Path("report.html"), help="HTML file (default report.html)")
    p.add_argument("--overwrite", action="store_true", help="replace an existing -o file (refused without it)")
    p.add_argument("--title", default="PMSM HIL run comparison", help="page title")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute `hil report`."""
    from pmsm_hil.dashboards.report_html import write_report
    from pmsm_hil.hil.atomic_write import atomic_path, refuse_existing, refuse_inputs
    from pmsm_hil.hil.runner.run_metadata import RUN_FILES

    refuse_inputs(args.output, [Path(d) / name for d in args.run_dirs for name in RUN_FILES], option="-o")
    refuse_existing(args.output, overwrite=args.overwrite, option="-o")
    with atomic_path(args.output, option="-o") as tmp:
        runs = write_report(args.run_dirs, tmp, args.title)
    print(f"report: {args.output} ({len(runs)} run{'s' if len(runs) != 1 else ''})")
    return 0
