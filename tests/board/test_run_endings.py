"""`hil run --target stm32g4:FW.elf`: an access to a register the virtual board does not model ends the run with one
line naming it (address, block or register, pc and function) — in a control period and in the firmware's start-up
alike, a safety stop (exit 3) with metrics.json and the log written, not a usage error; and the run's first period
is the board's outputs as they are (its open bridge before the firmware sets MOE), not the zero vector."""

from __future__ import annotations

import json
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.app.cli.main import main

TS = 50e-6


def hil(capsys: pytest.CaptureFixture[str], *args: str) -> subprocess.CompletedProcess[str]:
    """`hil run ARGS` in this process (what the tests read: the exit status, stderr and the outputs, as a `hil run`
    process leaves them; without its ≈ 0.6 CPU-s of start-up)."""
    capsys.readouterr()
    rc = main(["run", *args])
    return subprocess.CompletedProcess(["hil", "run", *args], rc, "", capsys.readouterr().err)


def hil_run(capsys: pytest.CaptureFixture[str], elf: Path, out: Path, *extra: str) -> subprocess.CompletedProcess[str]:
    return hil(capsys, "--target", f"stm32g4:{elf}", "--ts", str(TS), "--duration", "0.01", "--settle", "0.002",
               "--out", str(out), *extra)


def ending(proc: subprocess.CompletedProcess[str], out: Path) -> str:
    """The run's end reason (metrics.json), checked to be the one line hil run printed."""
    assert proc.returncode == 3, proc.stderr[-2000:]
    assert "Traceback" not in proc.stderr
    reason = str(json.loads((out / "metrics.json").read_text())["end_reason"])
    assert "\n" not in reason
    assert proc.stderr.strip().splitlines()[-1].startswith(f"hil: run ended (exit 3): {reason}")
    assert (out / "run.mcap").is_file()
    return reason



def _example_firmware() -> tuple[Path, Path]:
    """The example STM32G474 firmware's ELF (built) and its board file; skips without the ARM toolchain."""
    from pmsm_hil.sim_target.fw_build import build_firmware, missing_tools

    missing = missing_tools("stm32g474")
    if missing:
        pytest.skip(f"firmware board stm32g474: {', '.join(missing)} not installed")
    examples = Path(__file__).resolve().parents[2] / "examples"
    return build_firmware("stm32g474").path, examples / "stm32g4_foc" / "board.toml"


def test_an_unmodelled_register_in_the_start_up_ends_the_run_in_one_line_naming_it(
        build_fw: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    reason = ending(hil_run(capsys, build_fw("errors", "UNMODELLED_REGISTER"), out), out)
    assert reason.startswith("target stopped in its start-up, before the first period: write of TIM1 register at "
                             "offset 0x070 (0x40012c70), which the virtual board does not model, at pc 0x080")
    assert "(touch_tim1_reserved+0x" in reason


def test_an_unmodelled_peripheral_in_a_period_ends_the_run_in_one_line_naming_it(
        build_fw: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    reason = ending(hil_run(capsys, build_fw("pwm_adc", "UNMODELLED_AT=50"), out), out)
    assert reason.startswith("target stopped in period ")
    assert "write of 0x40010200 (SYSCFG/VREFBUF/COMP/OPAMP, not modelled by the virtual board) at pc 0x080" in reason
    assert "(ADC1_2_IRQHandler+0x" in reason


def test_a_fault_in_the_start_up_is_a_safety_stop_naming_pc_and_cfsr(
        build_fw: Callable[..., Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "run"
    reason = ending(hil_run(capsys, build_fw("errors", "FAULT_READ"), out), out)
    assert reason.startswith("target HardFault at pc 0x080")
    assert "(touch_nothing+0x" in reason and "PRECISERR" in reason and "in its start-up, before the first period" \
        in reason


def test_the_first_period_is_the_open_bridge_of_a_board_whose_outputs_are_off(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The example firmware keeps MOE = 0 until its first enabling Setpoint: on a machine spinning at 1500 rpm the
    host's period 0 is the open bridge (no current), where the zero vector drove ≈ 0.3 A into phases b and c."""
    from pmsm_hil.hil.runlog.reader import read_periods
    elf, board = _example_firmware()
    out = tmp_path / "run"
    proc = hil(capsys, "--target", f"stm32g4:{elf}",
               "--board", str(board), "--ts", str(TS), "--controller", "external", "--motor",
               "niu2020-ipmsm", "--speed", "1500", "--load", "7", "--duration", "0.001", "--settle",
               "0.001", "--out", str(out))
    assert proc.returncode in (0, 3), proc.stderr[-2000:]  # 40 periods: too short to judge the setpoint
    periods = read_periods(out / "run.mcap")
    first = periods[0]
    assert first["n_duties"] == 3 and first["n_states"] == 0
    duties = first["duties"][:3]
    assert 0.0 < min(duties) < max(duties) < 1.0 and max(duties) - min(duties) > 0.1  # the back EMF's, not 0.5
    # period 0's open bridge drives no current: the phase currents measured at the start of period 1 (from period 1
    # on the firmware may drive: its configuration, acknowledged at the bus rate of its FDCAN1, gives it the time to
    # calibrate its offsets before the run, and it enables the bridge at the first Setpoint)
    assert max(abs(periods[1][name]) for name in ("i_a", "i_b", "i_c")) < 0.01  # [A]


def test_the_board_periods_are_in_the_log(build_fw: Callable[..., Path], tmp_path: Path,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    """/board/periods: one message per control period; the late compares of the LATE firmware (its interrupt writes
    the compare values after the next update) counted per period add up to the run's `board_late_compares`."""
    from mcap.reader import make_reader

    out = tmp_path / "run"
    proc = hil_run(capsys, build_fw("pwm_adc", "LATE"), out)
    assert proc.returncode in (0, 3), proc.stderr[-2000:]
    metrics = json.loads((out / "metrics.json").read_text())
    with (out / "run.mcap").open("rb") as f:
        records = [json.loads(msg.data) for _, _, msg in make_reader(f).iter_messages(topics=["/board/periods"])]
    assert [r["period"] for r in records] == list(range(metrics["total_periods"]))
    assert sum(r["late_compares"] for r in records) == metrics["board_late_compares"] > 0
    assert all(r["isr_entries"] >= 1 and 0.0 < r["isr_us"] < TS * 1e6 and 0.0 < r["cpu_load"] <= 1.0
               for r in records[1:])
    assert records[5]["t"] == pytest.approx(5 * TS)


def test_the_python_reference_loop_applies_the_same_first_period(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`--loop python` (the test suite's reference loop) takes the board's first duties as the C loop does: the same
    records of the first periods."""
    from pmsm_hil.hil.runlog.reader import read_periods
    elf, board = _example_firmware()
    runs = []
    for loop in ("native", "python"):
        out = tmp_path / loop
        proc = hil(capsys, "--target", f"stm32g4:{elf}",
                   "--board", str(board), "--ts", str(TS), "--controller", "external", "--motor",
                   "niu2020-ipmsm", "--speed", "1500", "--load", "7", "--duration", "0.0005", "--settle",
                   "0.0005", "--loop", loop, "--out", str(out))
        assert proc.returncode in (0, 3), proc.stderr[-2000:]
        runs.append(read_periods(out / "run.mcap"))
    native, python = runs
    assert native[0]["n_duties"] == python[0]["n_duties"] == 3
    for name in ("duties", "i_a", "i_b", "i_c", "torque"):
        assert np.array_equal(native[name], python[name], equal_nan=True), name


def test_the_example_firmware_confirms_the_safe_stop_at_its_bus_rate(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The example firmware at its true 500 kbit/s (FDCAN1 on the HSE): a controller it does not implement gets a
    FaultTarget, and the safe stop's disabling Setpoint a FaultTarget then the HeartbeatTarget idle — the board
    runs idle periods until both have left the bus."""
    elf, board = _example_firmware()
    out = tmp_path / "run"
    proc = hil(capsys, "--target", f"stm32g4:{elf}",
               "--board", str(board), "--ts", str(TS), "--motor", "niu2020-ipmsm", "--speed", "1500",
               "--load", "7", "--duration", "0.002", "--settle", "0.001", "--out", str(out))
    assert proc.returncode == 3, proc.stderr[-2000:]
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["end_reason"].startswith("target fault code 6 (detail 1)")
    assert metrics["safe_stop_confirmed"] is True
    assert metrics["safe_stop_observed"] == "HeartbeatTarget state idle"
