"""`hil fw build`: builds the reference firmware or a user's firmware (CMake, docs/firmware_api.md) for the
host (a SIL library) or the emulated Cortex-M4F board mps2-an386 (an ELF for QEMU); prints the ELF's sizes."""

from __future__ import annotations

import argparse
from pathlib import Path

from pmsm_hil.sim_target.fw_build import ARTEFACT, BOARDS, build_firmware


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `build` under `hil fw`."""
    p = subparsers.add_parser(
        "build", help="build a firmware for the SIL host library or the QEMU mps2-an386 board",
        description="Build the reference firmware (default) or a firmware source folder (a CMakeLists.txt calling "
                    "hil_add_firmware(), e.g. examples/my_firmware/) for the host (shared library: hil run "
                    "--target sil:OUT) or mps2-an386 (Cortex-M4F ELF: hil run --target qemu:OUT); prints the "
                    "artefact's path and, for the ELF, its text/data/bss sizes.")
    p.add_argument("--board", choices=BOARDS, default="host", help="target board (default host)")
    p.add_argument("--src", type=Path, metavar="DIR", help="firmware source folder (default: the reference firmware)")
    p.add_argument("-o", "--out", type=Path, metavar="OUT",
                   help=f"output file or folder (default: {ARTEFACT['host']} / {ARTEFACT['mps2-an386']} in the "
                        "build cache)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute `hil fw build`."""
    result = build_firmware(args.board, args.src, args.out)
    print(f"built {result.path} ({result.board}, from {result.src})")
    if result.sizes is not None:
        s = result.sizes
        print(f"   text {s.text:>8} B   data {s.data:>6} B   bss {s.bss:>6} B   "
              f"(flash {s.flash} B, static RAM {s.ram} B incl. the stack)")
    return 0
