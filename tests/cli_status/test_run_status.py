"""`RunStatus`, the figures of `hil run`'s status line, from blocks of period records: counts, simulated time,
speed and torque of the last block, a real-time deadline miss warned once when it first happens and counted after,
and the live counter read between blocks."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from pmsm_hil.app.cli.run_status import RunStatus
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.records import PERIOD_DTYPE
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario


class FakeLine:
    """What RunStatus tells its StatusLine."""

    def __init__(self) -> None:
        self.calls: list[tuple[str, Any]] = []
        self.poll: Any = None

    def phase(self, text: str) -> None:
        self.calls.append(("phase", text))

    def total(self, n: int, unit: str) -> None:
        self.calls.append(("total", (n, unit)))

    def update(self, done: int | None = None, postfix: str | None = None) -> None:
        self.calls.append(("update", (done, postfix)))

    def warn(self, line: str) -> None:
        self.calls.append(("warn", line))


def _cfg() -> RunConfig:
    sc = load_scenario("steady").with_overrides(speed_rpm=1500.0, settle_s=0.1, duration_s=0.2)
    return RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc, controller="mpcc", target="qemu:/x/fw.elf")


def _block(n: int, rpm: float, torque: float, missed: tuple[int, ...] = ()) -> np.ndarray:
    rec = np.zeros(n, PERIOD_DTYPE)
    rec["omega_m"] = rpm * 2 * math.pi / 60
    rec["torque"] = torque
    for k in missed:
        rec["missed"][k] = 1
    return rec


def test_blocks_phases_and_deadline_warnings() -> None:
    line = FakeLine()
    status = RunStatus(line, _cfg())  # type: ignore[arg-type]
    assert line.calls[0] == ("phase", "starting target qemu:fw.elf…")
    status.phase("running")
    assert ("total", (3000, "periods")) in line.calls
    status.block(_block(1000, 1490.0, 6.5))
    status.block(_block(1000, 1500.0, 7.0, missed=(10, 20)))
    status.block(_block(1000, 1500.0, 7.0, missed=(5,)))
    warns = [c[1] for c in line.calls if c[0] == "warn"]
    assert warns == ["real time: period 1010 missed its deadline (counted in the metrics; the status line shows "
                     "the count)"]
    done, figures = next(c[1] for c in reversed(line.calls) if c[0] == "update")
    assert done == 3000
    assert figures.startswith("sim 0.300/0.300 s, ") and figures.endswith(", 1500 rpm, 7.00 N·m, 3 missed")


def test_the_live_counter_moves_the_count_between_blocks() -> None:
    line = FakeLine()
    status = RunStatus(line, _cfg())  # type: ignore[arg-type]
    status.phase("running")
    count = [0]
    status.counter(lambda: count[0])
    assert line.poll is not None
    count[0] = 420
    line.poll()
    done, figures = line.calls[-1][1]
    assert done == 420 and figures.startswith("sim 0.042/0.300 s") and "rpm" not in figures  # no block yet
    count[0] = 10_000  # never past the total
    line.poll()
    assert line.calls[-1][1][0] == 3000
