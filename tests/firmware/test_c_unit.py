"""Build the C firmware with CMake into tmp_path and run its unit tests through ctest."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware_stub"
OWN_TESTS = {"test_auth", "test_config", "test_controllers", "test_mpcc", "test_speed_pi", "test_step",
             "test_transforms"}

pytestmark = pytest.mark.skipif(shutil.which("cmake") is None, reason="cmake not installed")


@pytest.fixture(scope="module")
def build_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    build = tmp_path_factory.mktemp("fw_build")
    cfg = subprocess.run(["cmake", "-S", str(FIRMWARE), "-B", str(build)], capture_output=True, text=True,
                         timeout=300)
    assert cfg.returncode == 0, cfg.stdout + cfg.stderr
    out = subprocess.run(["cmake", "--build", str(build), "-j", "2"], capture_output=True, text=True,
                         timeout=600)
    assert out.returncode == 0, out.stdout + out.stderr
    return build


def test_every_c_test_is_registered(build_dir: Path) -> None:
    listed = subprocess.run(["ctest", "-N"], cwd=build_dir, capture_output=True, text=True, timeout=60)
    names = set(re.findall(r"Test +#\d+: (\S+)", listed.stdout))  # "Test  #1: a" ... "Test #10: b"
    expected = {p.stem for p in (FIRMWARE / "tests").glob("test_*.c")}
    assert expected >= OWN_TESTS
    assert names == expected


def test_ctest_passes(build_dir: Path) -> None:
    run = subprocess.run(["ctest", "--output-on-failure"], cwd=build_dir, capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "100% tests passed" in run.stdout


def test_firmware_built_with_strict_flags(build_dir: Path) -> None:
    flags = (build_dir / "CMakeFiles" / "hil_fw.dir" / "flags.make").read_text(encoding="utf-8")
    for flag in ("-std=c99", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion",
                 "-fsingle-precision-constant", "-O2"):
        assert flag in flags, flag


#: UBSan with float-to-integer cast checks (GCC leaves float-cast-overflow out of `undefined`); any finding aborts
UBSAN = "-fsanitize=undefined,float-cast-overflow -fno-sanitize-recover=all"


def test_ctest_passes_under_ubsan(tmp_path: Path) -> None:
    """The unit tests (NaN and out-of-range inputs to the generated encoders, a NaN flux sector, NaN/inf
    parameters) run clean under UBSan: no NaN or out-of-range float is ever cast to an integer."""
    cfg = subprocess.run(["cmake", "-S", str(FIRMWARE), "-B", str(tmp_path), f"-DCMAKE_C_FLAGS={UBSAN}",
                          "-DCMAKE_EXE_LINKER_FLAGS=-fsanitize=undefined"], capture_output=True, text=True, timeout=300)
    assert cfg.returncode == 0, cfg.stdout + cfg.stderr
    out = subprocess.run(["cmake", "--build", str(tmp_path), "-j", "2"], capture_output=True, text=True, timeout=600)
    if out.returncode != 0 and ("unrecognized" in out.stderr or "-lubsan" in out.stdout + out.stderr):
        pytest.skip("the C toolchain has no UBSan")
    assert out.returncode == 0, out.stdout + out.stderr
    run = subprocess.run(["ctest", "--output-on-failure"], cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0 and "runtime error" not in run.stdout + run.stderr, run.stdout + run.stderr
