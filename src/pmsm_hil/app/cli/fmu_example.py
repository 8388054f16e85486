"""`hil fmu example DIR`: writes the example load FMU (documented C source, modelDescription.xml) into DIR and
builds DIR/load_torque.fmu with the host's C compiler, ready for `hil run --load-fmu`."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `example` under `hil fmu`."""
    p = subparsers.add_parser(
        "example", help="write and build a documented example load FMU to start from",
        description="""Write load_torque.c (a load torque of Coulomb, viscous and quadratic parts through an
                       optional first-order lag; its comment documents the interface and parameters), fmi_glue.h
                       (the FMI calls in terms of the model), fmi_unused.c (the rest of the FMI API as stubs, for
                       tools such as fmpy) and the FMI 2.0 or 3.0 modelDescription.xml into DIR, and build
                       DIR/load_torque.fmu (Co-Simulation, Linux x86-64) with the host's C compiler against the FMI
                       headers fmpy ships. Run it with `hil run --load-fmu DIR/load_torque.fmu`; after editing,
                       rebuild with `hil fmu build DIR`.""")
    p.add_argument("dir", type=Path, metavar="DIR", help="folder to write into (created if missing)")
    p.add_argument("--fmi", type=int, choices=(2, 3), default=2, help="FMI version of the FMU (default 2)")
    p.add_argument("--overwrite", action="store_true", help="replace files of DIR that differ from the example")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute `hil fmu example`."""
    from pmsm_hil.hil.load_fmu.example import write_example

    files = write_example(args.dir, args.fmi, overwrite=args.overwrite)
    print(f"wrote {files.source} and {files.description} (FMI {args.fmi}.0)")
    print(f"built {files.fmu}")
    print(f"run it: hil run --load-fmu {files.fmu} --load-fmu-set k_quadratic=2e-4 --speed 1500")
    return 0
