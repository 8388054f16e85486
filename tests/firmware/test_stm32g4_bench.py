"""`hil bench loop --board stm32g4 FW.elf`: the board alone and the closed loop with the firmware as the controller
(`--controller external`); a closed-loop run that does not complete gives no figure but the way it ended.
Skipped without arm-none-eabi-gcc."""

from __future__ import annotations

from pathlib import Path

import pytest

from pmsm_hil.app.cli import bench_loop
from pmsm_hil.sim_target.fw_build import build_firmware, missing_tools

EXAMPLE_BOARD = str(Path(__file__).resolve().parents[2] / "examples" / "stm32g4_foc" / "board.toml")


def _elf() -> Path:
    missing = missing_tools("stm32g474")
    if missing:
        pytest.skip(f"firmware board stm32g474: {', '.join(missing)} not installed")
    return build_firmware("stm32g474").path


def test_the_closed_loop_figure_is_the_firmware_controlling_its_board() -> None:
    progress: list[str] = []
    out = bench_loop._board_rates(_elf(), EXAMPLE_BOARD, 50e-6, 0.01, 1, "1 run", progress.append)
    assert "lockstep_stm32g4_error" not in out, out
    assert out["lockstep_stm32g4_board_only_hz"] > 0 and out["lockstep_stm32g4_hz"] > 0, out
    assert 0.0 < out["stm32g4_cpu_load"] < 1.0, out
    assert any("closed loop" in line for line in progress)


def test_a_closed_loop_run_that_does_not_complete_gives_no_figure() -> None:
    # the bundled default board's front end (10 mV/A) is not the one the example firmware was built for (50 mV/A):
    # its current loop overshoots and the plant trips
    out = bench_loop._board_rates(_elf(), None, 50e-6, 0.02, 1, "1 run", lambda _msg: None)
    assert "lockstep_stm32g4_hz" not in out, out
    assert out["lockstep_stm32g4_error"].startswith("the closed-loop run ended with exit 3 (plant trip"), out
    assert out["lockstep_stm32g4_board_only_hz"] > 0
