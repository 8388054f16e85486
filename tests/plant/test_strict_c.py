"""The plant kernels compile cleanly under the project's strict C flags (the cffi build uses milder ones)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from pmsm_hil.hil.load_fmu.headers import fmi_include_dir

ROOT = Path(__file__).resolve().parents[2]
#: the package's C: the plant kernels (src/pmsm_hil/hil/kernels), the period loop (src/pmsm_hil/hil/runner/c) and its
#: links (src/pmsm_hil/hil/runner/c/links), the example load FMU users start from (`hil fmu example`)
HIL = ROOT / "src" / "pmsm_hil" / "hil"
KERNELS, LOOP_C, LINKS = HIL / "kernels", HIL / "runner" / "c", HIL / "runner" / "c" / "links"
FMU_EXAMPLE = HIL / "load_fmu" / "example_src"
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion", "-pedantic", "-O2"]
#: the period loop (loop*.c) includes the HIL target core and the generated codec
FIRMWARE = ROOT / "firmware_stub"
INCLUDES = [f"-I{FIRMWARE / d}" for d in ("target", "generated", "include")]
#: the load FMU's part of the loop includes the FMI standard headers of the installed fmpy (as the build does)
FMI = f"-I{fmi_include_dir()}"


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed")
@pytest.mark.parametrize("source", sorted(str(p.relative_to(HIL)) for p in HIL.rglob("*.c")))
def test_kernel_compiles_with_strict_flags(source: str, tmp_path: Path) -> None:
    result = subprocess.run(["gcc", *STRICT, *INCLUDES, FMI, *(f"-I{d}" for d in (KERNELS, LOOP_C, LINKS)), "-c",
                             str(HIL / source), "-o", str(tmp_path / "x.o")],
                            capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr


def test_every_c_folder_is_compiled() -> None:
    sources = {p.parent for p in HIL.rglob("*.c")}
    assert sources == {KERNELS, LOOP_C, LINKS, FMU_EXAMPLE}
