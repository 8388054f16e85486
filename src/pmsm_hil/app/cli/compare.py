"""`hil compare --preset NAME`: a paper experiment run closed loop per controller; table, JSON, CSV, PNG,
and with --report an HTML report of one operating point (src/pmsm_hil/app/compare/report_runs.py)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from pmsm_hil.app.cli.parsing import non_negative_int
from pmsm_hil.hil.atomic_write import atomic_path, refuse_inputs
from pmsm_hil.hil.errors import InputFileError


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `compare`."""
    from pmsm_hil.app.compare.preset import preset_names

    p = subparsers.add_parser(
        "compare", help="run a paper comparison preset (all its controllers) and print the table",
        description="Run every controller of a preset closed loop (in-process target, lockstep) and print "
                    "the comparison table with the paper's figures beside ours; writes NAME.json, NAME.csv "
                    "and NAME.png (where the paper has a figure) to --out. Presets: "
                    + ", ".join(preset_names()))
    p.add_argument("--preset", required=True, metavar="NAME", help="bundled preset name or a TOML file")
    p.add_argument("--out", type=Path, default=Path("compare"), metavar="DIR", help="output folder (%(default)s)")
    p.add_argument("--controllers", metavar="A,B", help="only these controllers (comma-separated)")
    p.add_argument("--report", nargs="?", const="", default=None, metavar="FILE",
                   help="also log one run per controller/variant (first point or largest sweep value, first "
                        "rotor angle; DIR/runs/NAME/LABEL with the 2 µs trace) and write a self-contained HTML "
                        "report of them to FILE (default DIR/NAME.html)")
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--workers", type=non_negative_int("--workers"), metavar="N",
                   help="worker processes (default: every core; 0: one run after the other in this process)")
    p.add_argument("--engine", choices=("local", "dask", "ray"), default="local",
                   help="where the runs go, as for `hil sweep` (docs/sweeps.md; default local process pool)")
    p.add_argument("--address", metavar="ADDR", help="Dask scheduler or Ray cluster address (--engine dask/ray)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute `hil compare`."""
    from pmsm_hil.app.compare.plot import write_png
    from pmsm_hil.app.compare.preset import load_preset
    from pmsm_hil.app.compare.report_runs import ReportSelection, dir_name, write_compare_report
    from pmsm_hil.app.compare.runs import run_preset
    from pmsm_hil.app.compare.table import format_table, write_csv, write_json
    from pmsm_hil.app.sweep.engines import open_engine
    from pmsm_hil.hil.runner.run_config import controller_id

    preset = load_preset(args.preset)
    if args.report and Path(args.preset).is_file():
        refuse_inputs(Path(args.report), [Path(args.preset)], option="--report")
    names = [c.strip() for c in args.controllers.split(",") if c.strip()] if args.controllers else None
    for name in names or preset.controllers:
        controller_id(name)
    try:
        args.out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InputFileError(f"--out {args.out}: {exc.strerror}") from None

    def progress(msg: str) -> None:
        if not args.quiet:
            print(msg, file=sys.stderr, flush=True)

    selection = (ReportSelection(preset, args.out / "runs" / dir_name(preset.name))
                 if args.report is not None else None)
    with open_engine(args.engine, workers=args.workers, address=args.address) as engine:
        progress(f"compare {preset.name}: on {engine.describe()}")
        result = run_preset(preset, controllers=names, progress=progress, run_dir=selection, engine=engine)
    for line in format_table(result):
        print(line)
    base = args.out / preset.name
    written: list[Path] = []
    for suffix, writer in ((".json", write_json), (".csv", write_csv), (".png", write_png)):
        path = base.with_suffix(suffix)
        with atomic_path(path, option="--out") as tmp:  # each file complete or the previous one kept
            if writer(result, tmp) is not False:  # write_png: False when the preset has no figure
                written.append(path)
    if selection is not None:
        html_path = Path(args.report) if args.report else base.with_suffix(".html")
        progress(f"report: rendering {len(selection.dirs)} logged run(s) into {html_path}")
        summary = write_compare_report(result, selection, html_path)
        written.append(summary.path)
        if summary.skipped:
            progress("report: skipped " + "; ".join(f"{n} ({why})" for n, why in summary.skipped))
    print("written: " + ", ".join(str(p) for p in written))
    return 0
