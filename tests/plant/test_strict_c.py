"""The plant kernels compile cleanly under the project's strict C flags (the cffi build uses milder ones)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from pmsm_hil.hil.load_fmu.headers import fmi_include_dir
from tests.plant.compile_cache import compile_ok

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
    """`source` compiles (a compile of the same bytes of every file it reads passed before: not run again)."""
    result = compile_ok(["gcc", *STRICT, *INCLUDES, FMI, *(f"-I{d}" for d in (KERNELS, LOOP_C, LINKS)), "-c",
                         str(HIL / source), "-o", str(tmp_path / "x.o")], tmp_path / "x.o")
    assert result is None or result.returncode == 0, result.stderr


def test_every_c_folder_is_compiled() -> None:
    sources = {p.parent for p in HIL.rglob("*.c")}
    assert sources == {KERNELS, LOOP_C, LINKS, FMU_EXAMPLE}


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed")
def test_a_kept_verdict_is_only_for_the_same_bytes(tmp_path: Path) -> None:
    """compile_ok: a passed compile is not run again for the same bytes; an edited header is compiled again and
    its error shown; a failure is never kept."""
    (tmp_path / "h.h").write_text("#define V 1\n", encoding="utf-8")  # a new path: a new key
    (tmp_path / "a.c").write_text('#include "h.h"\nint f(void) { return V; }\n', encoding="utf-8")
    cmd = ["gcc", *STRICT, "-c", str(tmp_path / "a.c"), "-o", str(tmp_path / "a.o")]
    first = compile_ok(cmd, tmp_path / "a.o")
    assert first is not None and first.returncode == 0, first
    assert compile_ok(cmd, tmp_path / "a.o") is None
    (tmp_path / "h.h").write_text("#define V undeclared_name\n", encoding="utf-8")
    for _ in range(2):
        failed = compile_ok(cmd, tmp_path / "a.o")
        assert failed is not None and failed.returncode != 0 and "undeclared_name" in failed.stderr
