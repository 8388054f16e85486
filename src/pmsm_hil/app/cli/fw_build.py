"""`hil fw build`: builds the reference firmware or a user's firmware (CMake, docs/firmware_api.md) for the
host (a SIL library), the emulated Cortex-M4F board mps2-an386 (an ELF for QEMU) or the virtual STM32G474 (a
bare-metal ELF, by default examples/stm32g4_foc); prints the compiler's
warnings (count and first lines), the ELF's sizes and the firmware's declared parameters."""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from pmsm_hil.app.cli.status_line import StatusLine, status_wanted
from pmsm_hil.sim_target.fw_build import ARTEFACT, BOARDS, SHOWN_WARNINGS, build_firmware
from pmsm_hil.sim_target.fw_params import firmware_params


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `build` under `hil fw`."""
    p = subparsers.add_parser(
        "build", help="build a firmware for the SIL host library, the QEMU mps2-an386 board or the virtual STM32G474",
        description="""Build the reference firmware (default) or a firmware source folder (a CMakeLists.txt calling
                       hil_add_firmware(), e.g. examples/my_firmware/ or the C++ examples/my_firmware_cpp/) for the host
                       (shared library: hil run --target sil:OUT), mps2-an386 (Cortex-M4F ELF: hil run --target
                       qemu:OUT) or stm32g474 (the ELF for a NUCLEO-G474RE and hil run --target stm32g4:OUT: a
                       hil_add_firmware() folder on the board layer, its frames on FDCAN1, or a bare-metal firmware
                       owning its start-up and peripherals, default source examples/stm32g4_foc); prints the
                       artefact's path, the compiler's warnings, for the ELF its text/data/bss sizes, and the
                       parameters the firmware declares (hil_app_params.h).""")
    p.add_argument("--board", choices=BOARDS, default="host", help="target board (default host)")
    p.add_argument("--src", type=Path, metavar="DIR",
                   help="firmware source folder (default: the reference firmware; for stm32g474 examples/stm32g4_foc)")
    p.add_argument("-o", "--out", type=Path, metavar="OUT",
                   help=f"output file or folder (default: {ARTEFACT['host']} / {ARTEFACT['mps2-an386']} in the "
                        "build cache)")
    p.add_argument("--define", action="append", default=[], metavar="NAME=VALUE",
                   help="preprocessor macro of the firmware and CMake variable (repeatable), e.g. "
                        "MY_FW_BANDWIDTH=2000.0f or HIL_FP_CONTRACT=fast")
    p.add_argument("--verbose", action="store_true",
                   help="show the commands and the whole build output (CMake runs even when the cache has the build)")
    p.add_argument("--no-cache", action="store_true",
                   help="run CMake (an incremental build) even when the build cache has a firmware built from the "
                        "same sources, SDK, board, defines and tools")
    p.add_argument("--quiet", action="store_true", help="no live status line (drawn only on a terminal)")
    p.set_defaults(func=run)


#: CMake's progress prefix of a build line: "[ 45%] Building C object ..."
_PERCENT = re.compile(r"^\[\s*(\d+)%\]\s*(.*)")


class _BuildStatus:
    """The status line of a build: the step, CMake's percentage and what it builds now."""

    def __init__(self, line: StatusLine) -> None:
        self.line = line
        self.step = ""

    def __call__(self, step: str, text: str) -> None:
        if step != self.step:
            self.step = step
            self.line.phase(step)
            if step == "building":
                self.line.total(100, "%")
        m = _PERCENT.match(text)
        if m is not None:
            self.line.update(int(m.group(1)), _what(m.group(2)))
        elif " warning: " in text:
            self.line.warn(text.strip())


def _what(text: str) -> str:
    """CMake's words for a step, short: `Building C object CMakeFiles/x.dir/a/b/foo.c.o` -> `compiling foo.c`."""
    if text.startswith("Building ") and " object " in text:
        return "compiling " + text.rsplit("/", 1)[-1].removesuffix(".o").removesuffix(".obj")
    return text[:60]


def run(args: argparse.Namespace) -> int:
    """Execute `hil fw build`."""
    with StatusLine("hil fw build", enabled=status_wanted(args.quiet or args.verbose)) as status:
        status.phase("starting")
        result = build_firmware(args.board, args.src, args.out, defines=args.define, verbose=args.verbose,
                                progress=_BuildStatus(status) if status.enabled else None,
                                use_cache=not args.no_cache)
        status.close("done")
    if result.warnings:
        n = len(result.warnings)
        print(f"{n} compiler warning{'s' if n != 1 else ''}:", file=sys.stderr)
        for line in result.warnings[:SHOWN_WARNINGS]:
            print(f"    {line}", file=sys.stderr)
        if n > SHOWN_WARNINGS:
            print(f"    ... and {n - SHOWN_WARNINGS} more (--verbose shows them all)", file=sys.stderr)
    print(f"built {result.path} ({result.board}, from {result.src})")
    if result.sizes is not None:
        s = result.sizes
        print(f"   text {s.text:>8} B   data {s.data:>6} B   bss {s.bss:>6} B   "
              f"(flash {s.flash} B, static RAM {s.ram} B incl. the stack)")
    for p in firmware_params(result.path):
        print(f"   firmware parameter {p.name} (id {p.id}, {p.unit or 'no unit'}): default {p.default:g}, "
              f"range [{p.min:g}, {p.max:g}]  -> hil run --param {p.name}=VALUE")
    return 0
