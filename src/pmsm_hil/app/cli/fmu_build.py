"""`hil fmu build DIR`: builds DIR/<modelIdentifier>.fmu from DIR's C files and modelDescription.xml (the folder
`hil fmu example` wrote, after an edit)."""

from __future__ import annotations

import argparse
from pathlib import Path


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `build` under `hil fmu`."""
    p = subparsers.add_parser(
        "build", help="build DIR/<modelIdentifier>.fmu from DIR's C files and modelDescription.xml",
        description="""Compile every *.c file of DIR with the host's C compiler ($CC, else gcc or cc; -std=c99 -Wall
                       -Wextra -Werror, -DLOAD_FMI=2 or 3 after the description's fmiVersion) against the FMI
                       headers fmpy ships, and zip the library with DIR/modelDescription.xml as
                       DIR/<modelIdentifier>.fmu (FMI 2.0: binaries/linux64, 3.0: binaries/x86_64-linux).""")
    p.add_argument("dir", type=Path, metavar="DIR", help="folder with the C source(s) and modelDescription.xml")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute `hil fmu build`."""
    from pmsm_hil.hil.load_fmu.example import build_folder

    print(f"built {build_folder(args.dir)}")
    return 0
