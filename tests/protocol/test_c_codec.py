"""Build and run the C codec test (firmware_stub/tests/test_codec.c) with gcc, without CMake."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest

from pmsm_hil.protocol.paths import GENERATED_C_DIR, GOLDEN_C_HEADER

#: the firmware's strict flags (src/pmsm_hil/sim_target/_build_firmware.py STRICT_FLAGS), at -O1
FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion", "-fsingle-precision-constant", "-O1"]
TEST_C = GOLDEN_C_HEADER.parent / "test_codec.c"

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc not installed")


def test_generated_codec_compiles_with_firmware_flags(tmp_path: Path) -> None:
    out = subprocess.run(
        [
            "gcc",
            *FLAGS,
            "-c",
            str(GENERATED_C_DIR / "hil_protocol.c"),
            "-o",
            str(tmp_path / "hil_protocol.o"),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert out.returncode == 0, out.stderr


def test_c_codec_golden_and_round_trips(tmp_path: Path) -> None:
    exe = tmp_path / "test_codec"
    build = subprocess.run(
        [
            "gcc",
            *FLAGS,
            f"-I{GENERATED_C_DIR}",
            f"-I{GOLDEN_C_HEADER.parent}",
            str(TEST_C),
            str(GENERATED_C_DIR / "hil_protocol.c"),
            "-lm",
            "-o",
            str(exe),
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True, check=False, timeout=60)
    assert run.returncode == 0, run.stdout + run.stderr
    assert "0 failure(s)" in run.stdout
    assert int(run.stdout.split("test_codec: ")[1].split()[0]) >= 28  # all distinct golden frames ran
