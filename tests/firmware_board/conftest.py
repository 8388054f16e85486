"""Fixtures of the bring-your-own-firmware tests: firmware builds (once per session) and the tool checks.

Tests skip with a clear reason only when the tools are absent (CI installs them: .ci/run)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from pmsm_hil.sim_target.fw_build import build_firmware, missing_tools

ROOT = Path(__file__).resolve().parents[2]
TEMPLATE = ROOT / "examples" / "my_firmware"


def need(board: str) -> None:
    """Skip unless the tools for `board` (and QEMU for the MCU board) are installed."""
    missing = missing_tools(board)
    if board == "mps2-an386" and shutil.which("qemu-system-arm") is None:
        missing.append("qemu-system-arm")
    if missing:
        pytest.skip(f"firmware board {board}: {', '.join(missing)} not installed")


def built(board: str, src: Path) -> Path:
    """The firmware in `src` built for `board` (skipped without its tools), with no compiler warning."""
    need(board)
    build = build_firmware(board, src)
    assert build.warnings == ()
    return build.path


@pytest.fixture(scope="session")
def reference_sil() -> Path:
    need("host")
    return build_firmware("host").path


@pytest.fixture(scope="session")
def reference_elf() -> Path:
    need("mps2-an386")
    return build_firmware("mps2-an386").path


@pytest.fixture(scope="session")
def template_sil() -> Path:
    need("host")
    return build_firmware("host", TEMPLATE).path


@pytest.fixture(scope="session")
def template_elf() -> Path:
    need("mps2-an386")
    return build_firmware("mps2-an386", TEMPLATE).path
