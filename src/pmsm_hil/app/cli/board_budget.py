"""`hil link-budget --board stm32g474`: the link's wire time plus the firmware's own time on the MCU per period, from
the instructions it executes on the virtual board (CPI 1: one cycle per instruction, a lower bound), give the
highest closed-loop rate a real bench with that board can reach (lockstep and real time alike: a Measurement, the
MCU's turnaround and the Command fit in one period)."""

from __future__ import annotations

import tempfile
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from pmsm_hil.protocol.errors import BudgetError
from pmsm_hil.protocol.links.budget import LinkBudget

#: boards `--board` takes: the firmware API's MCU board layers that carry the frames on CAN (FD)
BUDGET_BOARDS = ("stm32g474",)
#: the board layer's core clock [Hz] (firmware_stub/boards/stm32g474/board.h HIL_BOARD_SYSCLK_HZ)
BOARD_CLOCK_HZ = {"stm32g474": 170_000_000.0}
#: the firmware measured when none is named: the template
DEFAULT_FIRMWARE = Path(__file__).resolve().parents[4] / "examples" / "my_firmware"
#: the measuring run: the rated point of niu2020 at 5 kHz, settled for MEASURE_SETTLE_S, measured MEASURE_S [s]
MEASURE_TS_S = 200e-6
MEASURE_SETTLE_S = 0.01
MEASURE_S = 0.03


@dataclass(frozen=True, slots=True)
class Turnaround:
    """The MCU's share of a control period: from a Measurement's arrival to the start of its Command [cycles]."""

    firmware: str
    cycles_median: float
    cycles_max: float
    clock_hz: float
    source: str  # "measured" (a run on the virtual board) or "given" (--instructions)
    command_form: str | None = None  # the Command form the firmware sent ("states", "duties"), when measured


@dataclass(frozen=True, slots=True)
class BoardBudget:
    """The link's budget with the MCU's turnaround added."""

    board: str
    turnaround: Turnaround
    period_us: float  # wire time per period + the worst MCU turnaround
    max_rate_hz: float
    feasible: bool | None

    def as_dict(self) -> dict[str, Any]:
        t = self.turnaround
        return {"board": self.board, "firmware": t.firmware, "source": t.source, "clock_hz": t.clock_hz,
                "command_form": t.command_form,
                "turnaround_cycles": {"median": t.cycles_median, "max": t.cycles_max},
                "turnaround_us": t.cycles_max / t.clock_hz * 1e6, "period_us": self.period_us,
                "max_rate_hz": self.max_rate_hz, "feasible": self.feasible}


def firmware_elf(board: str, firmware: Path | None) -> Path:
    """The ELF to measure: `firmware` itself when it is a file, else the folder (default: the template) built for
    `board` (`hil fw build`, cached)."""
    from pmsm_hil.sim_target.fw_build import build_firmware

    src = DEFAULT_FIRMWARE if firmware is None else firmware.expanduser()
    if src.is_file():
        return src
    if not src.is_dir():
        raise BudgetError(f"--firmware {src}: no such ELF or source folder")
    return build_firmware(board, src).path


def measure_turnaround(board: str, elf: Path, *, label: str) -> Turnaround:
    """Run the firmware at the rated point on the virtual board (its frames on FDCAN1) and take the MCU's
    turnaround per period from the run's metrics."""
    from pmsm_hil.hil.presets_loader import load_motor
    from pmsm_hil.hil.runlog.reader import read_periods
    from pmsm_hil.hil.runner.run import run_closed_loop
    from pmsm_hil.hil.runner.run_config import RunConfig
    from pmsm_hil.hil.runner.scenario import load_scenario

    scenario = load_scenario("steady").with_overrides(speed_rpm=1500.0, load_nm=7.0, settle_s=MEASURE_SETTLE_S,
                                                      duration_s=MEASURE_S)
    with tempfile.TemporaryDirectory(prefix="hil-link-budget-") as out:
        cfg = replace(RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=scenario, controller="external"),
                      target=f"stm32g4:{elf}", ts_s=MEASURE_TS_S, out_dir=Path(out))
        metrics = run_closed_loop(cfg).metrics
        mcap = Path(out) / "run.mcap"
        records = read_periods(mcap) if mcap.is_file() else None
    form = None if records is None or not len(records) else \
        "duties" if bool((records["n_duties"] > 0).any()) else "states"
    turn = metrics.get("board_turnaround_cycles")
    if metrics.get("end_code") != 0 or not isinstance(turn, dict):
        raise BudgetError(f"--firmware {label}: the measuring run on the virtual {board} did not complete "
                          f"({metrics.get('end_reason', 'no turnaround measured')}); an image built with "
                          f"`hil fw build --board {board} --src DIR` is needed")
    return Turnaround(label, float(turn["median"]), float(turn["max"]), float(metrics["mcu_clock_hz"]), "measured",
                      form)


def board_budget(board: str, link: LinkBudget, turnaround: Turnaround) -> BoardBudget:
    """Wire time of the period plus the worst turnaround: the highest rate, and whether `link.rate_hz` fits."""
    period_us = link.wire_time_per_period_us + turnaround.cycles_max / turnaround.clock_hz * 1e6
    rate = 1e6 / period_us
    feasible = None if link.rate_hz is None else link.rate_hz <= rate
    return BoardBudget(board, turnaround, period_us, rate, feasible)


def format_board_budget(b: BoardBudget) -> str:
    t = b.turnaround
    how = "on the virtual board: instructions at CPI 1 and exception entries, a lower bound" \
        if t.source == "measured" else "--instructions"
    verdict = "" if b.feasible is None else "  (fits)" if b.feasible else "  (TOO SLOW)"
    return "\n".join([
        f"  board {b.board} @ {t.clock_hz / 1e6:g} MHz, firmware {t.firmware}: MCU turnaround {t.cycles_max:.0f} "
        f"cycles worst, {t.cycles_median:.0f} median ({how}) = {t.cycles_max / t.clock_hz * 1e6:.1f} µs",
        f"  per period with the firmware: {b.period_us:.1f} µs (wire + MCU)",
        f"  achievable closed-loop rate with the firmware: {b.max_rate_hz:.0f} Hz{verdict}",
    ])
