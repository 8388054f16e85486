"""The virtual board runs only when the host polls it: the configuration's resends follow the board (it stopped
without answering), never the host's wall clock, so a host too slow for every resend interval configures the
firmware exactly as an idle one does and the run's records are the same bit for bit."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.runlog.reader import read_frames, read_periods
from pmsm_hil.hil.runner.run import run_from_options
from pmsm_hil.hil.runner.target_client import TargetClient
from tests.board.test_run_endings import TS, _example_firmware


def _run(out: Path) -> dict[str, Any]:
    elf, board = _example_firmware()
    res = run_from_options({"target": f"stm32g4:{elf}", "board": str(board), "ts": TS, "link": "virtual",
                            "controller": "external", "motor": "niu2020-ipmsm", "speed": 1500, "load": 7,
                            "duration": 0.005, "settle": 0.0, "out": str(out)})
    return res.metrics


def test_a_host_past_every_resend_interval_configures_the_board_as_an_idle_host(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    idle = _run(tmp_path / "idle")
    timeout_s = (TargetClient.configure.__defaults__ or (10.0,))[0]
    monkeypatch.setattr(TargetClient.configure, "__defaults__", (timeout_s, 0.0))  # every wall-time check is late
    slow = _run(tmp_path / "slow")
    assert idle["end_code"] == slow["end_code"] == 0, (idle["end_reason"], slow["end_reason"])
    assert idle["link"]["config_resent"] == slow["link"]["config_resent"]
    assert idle["board_idle_periods"] == slow["board_idle_periods"]
    a, b = read_periods(tmp_path / "idle" / "run.mcap"), read_periods(tmp_path / "slow" / "run.mcap")
    assert len(a) >= round(0.005 / TS) - 1 and a.tobytes() == b.tobytes()
    assert np.array_equal(read_frames(tmp_path / "idle" / "run.mcap"), read_frames(tmp_path / "slow" / "run.mcap"))
