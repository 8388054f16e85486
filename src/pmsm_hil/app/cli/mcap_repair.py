"""`hil mcap-repair IN.mcap [-o OUT.mcap]`: recover the valid prefix of a cut MCAP run log."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from pmsm_hil.hil.atomic_write import refuse_inputs
from pmsm_hil.hil.errors import InputFileError


def add_parser(subparsers: Any) -> argparse.ArgumentParser:
    """Register the `mcap-repair` sub-command on an argparse sub-parser collection."""
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "mcap-repair",
        help="rewrite the valid prefix of a cut MCAP run log as a complete file",
        description="""Read IN.mcap chunk by chunk up to the first incomplete or corrupt record and write a complete,
                       indexed MCAP file (default OUT: IN.repaired.mcap).""",
    )
    parser.add_argument("input", type=Path, metavar="IN.mcap", help="MCAP file to repair")
    parser.add_argument("-o", "--output", type=Path, metavar="OUT.mcap", default=None, help="output file")
    parser.add_argument("--overwrite", action="store_true",
                        help="replace an existing OUT (without it any existing OUT is kept and the command exits 2)")
    parser.set_defaults(func=run)
    return parser


def run(args: argparse.Namespace) -> int:
    """Run the repair; prints a one-paragraph report. Returns 0; errors (RunLogError, InputFileError; an
    existing OUT without --overwrite) are printed by `hil` as one line, exit 2, and
    leave an existing OUT untouched."""
    src: Path = args.input
    dst: Path = args.output if args.output is not None else src.with_suffix(".repaired.mcap")
    if not src.is_file():
        raise InputFileError(f"IN.mcap {src}: is not a file")
    refuse_inputs(dst, [src], option="-o")
    from pmsm_hil.hil.runlog.repair import repair_mcap  # numpy and mcap: imported when a file is repaired

    report = repair_mcap(src, dst, overwrite=args.overwrite)
    state = "complete" if report.source_complete else f"cut ({report.stop_reason})"
    topics = ", ".join(f"{t}: {n}" for t, n in sorted(report.messages_per_topic.items())) or "none"
    print(
        f"{src}: {state}; kept {report.valid_bytes} of {report.src_bytes} bytes, {report.chunks} chunk(s), "
        f"{report.messages} message(s) [{topics}], {report.metadata_records} metadata record(s) -> {dst}"
    )
    return 0
