"""Build the C firmware with CMake (a cached tree: tests/firmware/_cmake_cache.py) and run its unit tests through
ctest."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from tests.firmware._cmake_cache import CMakeBuildError, cmake_tree, ctest

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware_stub"
OWN_TESTS = {"test_auth", "test_config", "test_controllers", "test_mpcc", "test_speed_pi", "test_step",
             "test_transforms"}

pytestmark = pytest.mark.skipif(shutil.which("cmake") is None, reason="cmake not installed")


@pytest.fixture(scope="module")
def build_dir() -> Path:
    """firmware_stub built with its own flags (a tree shared by the user's pytest processes, rebuilt when any file
    of firmware_stub changes: tests/firmware/_cmake_cache.py)."""
    return cmake_tree("c-unit", FIRMWARE)


def test_every_c_test_is_registered(build_dir: Path) -> None:
    listed = ctest(build_dir, "-N", timeout_s=60)
    names = set(re.findall(r"Test +#\d+: (\S+)", listed.stdout))  # "Test  #1: a" ... "Test #10: b"
    expected = {p.stem for p in (FIRMWARE / "tests").glob("test_*.c")}
    assert expected >= OWN_TESTS
    assert names == expected


def test_ctest_passes(build_dir: Path) -> None:
    run = ctest(build_dir, "--output-on-failure")
    assert run.returncode == 0, run.stdout + run.stderr
    assert "100% tests passed" in run.stdout


def test_firmware_built_with_strict_flags(build_dir: Path) -> None:
    flags = (build_dir / "CMakeFiles" / "hil_fw.dir" / "flags.make").read_text(encoding="utf-8")
    for flag in ("-std=c99", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion",
                 "-fsingle-precision-constant", "-O2"):
        assert flag in flags, flag


#: UBSan with float-to-integer cast checks (GCC leaves float-cast-overflow out of `undefined`); any finding aborts
UBSAN = "-fsanitize=undefined,float-cast-overflow -fno-sanitize-recover=all"


def test_ctest_passes_under_ubsan() -> None:
    """The unit tests (NaN and out-of-range inputs to the generated encoders, a NaN flux sector, NaN/inf
    parameters) run clean under UBSan: no NaN or out-of-range float is ever cast to an integer."""
    try:
        tree = cmake_tree("c-unit-ubsan", FIRMWARE, [f"-DCMAKE_C_FLAGS={UBSAN}",
                                                     "-DCMAKE_EXE_LINKER_FLAGS=-fsanitize=undefined"])
    except CMakeBuildError as exc:
        if "unrecognized" in str(exc) or "-lubsan" in str(exc):
            pytest.skip("the C toolchain has no UBSan")
        raise
    run = ctest(tree, "--output-on-failure")
    assert run.returncode == 0 and "runtime error" not in run.stdout + run.stderr, run.stdout + run.stderr
