"""The template firmware (examples/my_firmware) on the firmware API's STM32G474 board layer
(firmware_stub/boards/stm32g474/): `hil fw build --board stm32g474 --src` gives the ELF a NUCLEO-G474RE is flashed
with, and on the virtual board (`--target stm32g4:`) it holds the rated point over the board's emulated FDCAN1 with
the records of its `sil:` run."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.runlog.reader import read_periods
from pmsm_hil.sim_target.elf import elf_symbols
from pmsm_hil.sim_target.fw_build import build_firmware
from pmsm_hil.sim_target.stm32g4.frame_link import is_core_image
from tests.firmware_board._runs import metrics, rated
from tests.firmware_board.conftest import ROOT, TEMPLATE, need

#: metrics of the machinery, not of the firmware's control: wall time, link statistics, execution time, the board's
TIMING = {"wall_time_s", "loop_rate_hz", "exec_time_us", "exec_time_first_us", "link", "safe_stop_wait_ms",
          "command_wait_max_us", "total_wall_time_s", "loop_rate_total_hz", "link_spec", "target_link", "link_losses",
          "link_auth_dropped"}
TIMING_COLUMNS = {"exec_time_ns", "exec_split_ns"}


@pytest.fixture(scope="module")
def template_g4() -> Path:
    need("stm32g474")
    build = build_firmware("stm32g474", TEMPLATE)
    assert build.warnings == ()
    return build.path


def _check(m: dict[str, Any]) -> None:
    assert m["dut_violations"] == 0
    assert m["speed_mean_rpm"] == pytest.approx(1500.0, rel=0.005)
    assert m["torque_mean_nm"] == pytest.approx(7.0, rel=0.01)
    assert m["torque_ripple_rms_nm"] < 0.2


def test_the_image_is_the_board_layer_around_the_target_core(template_g4: Path) -> None:
    symbols = elf_symbols(template_g4)
    assert is_core_image(template_g4)
    for name in ("hil_core_rx", "hil_app_step", "FDCAN1_IT0_IRQHandler", "Reset_Handler", "__libc_init_array",
                 "hil_fault_report"):
        assert name in symbols, name
    assert symbols["hil_vectors"] == 0x0800_0000  # the vector table at the start of flash
    foc = build_firmware("stm32g474", ROOT / "examples" / "stm32g4_foc").path  # bare metal: TIM1 and the ADCs
    assert not is_core_image(foc)


def test_template_on_the_virtual_board_has_the_records_of_sil(template_g4: Path, template_sil: Path,
                                                              tmp_path: Path) -> None:
    runs = {}
    for kind, path in (("sil", template_sil), ("stm32g4", template_g4)):
        out = tmp_path / kind
        runs[kind] = (metrics(rated(f"{kind}:{path}", controller="external", settle_s=0.03, duration_s=0.07,
                                    out_dir=out)), read_periods(out / "run.mcap"))
    (m_sil, rec_sil), (m_g4, rec_g4) = runs["sil"], runs["stm32g4"]
    _check(m_sil)
    _check(m_g4)
    assert m_g4["board_link"] == "fdcan1"
    assert m_g4["board_can_bitrates"] == [1_000_000, 5_000_000]
    assert m_g4["board_late_replies"] == 0 and m_g4["board_missing_replies"] == 0
    turn = m_g4["board_turnaround_cycles"]
    assert 500 < turn["median"] <= turn["max"] < 20_000
    # the step's own time from the DWT cycle counter: below the turnaround (which adds the frames' handling)
    assert 0 < m_g4["exec_time_us"]["median"] < m_g4["board_turnaround_us"]["median"]
    shared = sorted(set(m_sil) & set(m_g4) - TIMING)
    assert len(shared) > 30
    assert {k: m_sil[k] for k in shared} == {k: m_g4[k] for k in shared}
    assert len(rec_sil) == len(rec_g4) > 900
    for name in rec_sil.dtype.names:
        if name not in TIMING_COLUMNS and name != "torque_ref":  # torque_ref: SIL's debug output only
            assert np.array_equal(rec_sil[name], rec_g4[name], equal_nan=True), name


def test_link_budget_with_the_board(template_g4: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["link-budget", "--board", "stm32g474", "--link", "canfd", "--firmware", str(template_g4),
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    board = out["with_board"]
    assert board["source"] == "measured" and board["clock_hz"] == 170e6
    turn_us = board["turnaround_us"]
    assert board["period_us"] == pytest.approx(out["wire_time_per_period_us"] + turn_us)
    assert board["max_rate_hz"] == pytest.approx(1e6 / board["period_us"])
    assert board["max_rate_hz"] < out["max_rate_hz"]  # the MCU's time costs rate
    # given instead of measured; too slow for the asked rate: exit 1, the figures printed
    assert main(["link-budget", "--board", "stm32g474", "--link", "canfd", "--instructions", "17000",
                 "--rate", "10000"]) == 1
    text = capsys.readouterr()
    assert "MCU turnaround 17000" in text.out and "100.0 µs" in text.out
    assert "too slow" in text.err and "stm32g474" in text.err


def test_link_budget_board_options_are_checked(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["link-budget", "--link", "canfd", "--instructions", "500"]) == 2  # no --board
    assert "--firmware and --instructions go with --board" in capsys.readouterr().err
    assert main(["link-budget", "--board", "stm32g474", "--link", "serial", "--instructions", "500"]) == 2
    assert "use --link can or canfd, got --link serial" in capsys.readouterr().err
    assert main(["link-budget", "--board", "stm32g474", "--link", "canfd", "--instructions", "0"]) == 2
    assert "--instructions must be a positive number" in capsys.readouterr().err
    assert main(["link-budget", "--board", "stm32g474", "--link", "canfd", "--firmware", "/nonexistent/fw"]) == 2
    assert "--firmware /nonexistent/fw: no such ELF or source folder" in capsys.readouterr().err


def test_link_budget_with_given_instructions_adds_the_mcu_time(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["link-budget", "--board", "stm32g474", "--link", "canfd", "--instructions", "1700",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    board = out["with_board"]
    assert board["turnaround_us"] == pytest.approx(10.0)  # 1700 cycles at 170 MHz
    assert board["period_us"] == pytest.approx(out["wire_time_per_period_us"] + 10.0)
    assert board["max_rate_hz"] == pytest.approx(1e6 / board["period_us"])
