"""`hil replay` of a duty-cycle firmware's run on `sil:` (the template user firmware: three duty cycles of a
centre-aligned PWM each period, CmdDutyFd): the run's MCAP and its candump export give back the logged currents."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from pmsm_hil.hil.runlog.can_log import export_frames
from pmsm_hil.hil.runlog.reader import read_periods
from pmsm_hil.hil.runner.replay_run import replay_run
from pmsm_hil.hil.runner.run import run_closed_loop
from tests.firmware_board._runs import rated


def test_replay_of_a_duty_cycle_firmware_on_sil_gives_the_logged_currents(template_sil: Path, tmp_path: Path) -> None:
    cfg = replace(rated(f"sil:{template_sil}", controller="external", settle_s=0.005, duration_s=0.015),
                  out_dir=tmp_path / "run")
    res = run_closed_loop(cfg)
    assert res.metrics["end_code"] == 0, res.metrics["end_reason"]
    assert res.mcap_path is not None
    periods = read_periods(res.mcap_path)
    assert (periods["n_duties"][1:] == 3).all()  # the firmware sends duty cycles
    log = tmp_path / "run.log"
    export_frames(res.mcap_path, "candump", log)
    logged = np.column_stack([periods[n] for n in ("i_a", "i_b", "i_c")])
    for capture in (None, log):
        out = tmp_path / f"replay-{capture is None}.csv"
        done = replay_run(res.mcap_path, out, capture=capture)
        replayed = np.loadtxt(out, delimiter=",", skiprows=1)[:len(periods), 1:4]
        assert np.max(np.abs(replayed - logged)) <= 1e-6
        assert done.compared == len(periods) > 150 and done.max_error_a <= 1e-6
