"""`hil replay` of a run whose load is an FMU: the load torque each period logged (the FMU's output, held over the
period as the loop held it) drives the replayed mechanics, and the logged currents come back."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from pmsm_hil.hil.runlog.reader import read_periods
from pmsm_hil.hil.runner.replay_run import replay_run
from pmsm_hil.hil.runner.run import run_closed_loop
from tests.load_fmu.test_load_fmu import _config


def test_replay_of_a_run_with_an_fmu_load_gives_the_logged_currents(fan_fmus: dict[int, Path],
                                                                     tmp_path: Path) -> None:
    cfg = replace(_config(fan_fmus[2], settle_s=0.005, duration_s=0.015), out_dir=tmp_path / "run")
    res = run_closed_loop(cfg)
    assert res.metrics["end_code"] == 0, res.metrics["end_reason"]
    assert res.mcap_path is not None
    periods = read_periods(res.mcap_path)
    assert np.ptp(periods["load_torque"]) > 0.0  # the fan's torque follows the speed
    done = replay_run(res.mcap_path, tmp_path / "replay.csv")
    assert done.compared == len(periods) and done.max_error_a <= 1e-6
