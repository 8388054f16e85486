"""Loop rate with the live Rerun dashboard on (for `hil bench loop`)."""

from __future__ import annotations

import statistics
import tempfile
from pathlib import Path
from typing import Any

from pmsm_hil.dashboards.live import LiveRerun
from pmsm_hil.dashboards.recording import RerunTargets
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig


def live_rerun_rate(cfg: RunConfig, repeats: int) -> dict[str, Any]:
    """Median closed-loop periods/s with every block streamed live to Rerun (an .rrd sink in a temporary
    directory: the same process, ring and `send_columns` path as a viewer, without needing a display).

    The dashboard process starts before the timed loop; `stall_s` is time the loop waited for it."""
    rates: list[float] = []
    stall = 0.0
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(max(repeats, 1)):
            with LiveRerun(RerunTargets(save=Path(tmp) / f"live{i}.rrd"), vdc=cfg.motor.vdc, ts_s=cfg.ts_s) as live:
                res = run_closed_loop(cfg, live=live.submit_periods)
                live.flush()
                stall += live.stall_s
            rates.append(res.outcome.completed_periods / res.outcome.wall_time_s)
    return {"periods_per_s": statistics.median(rates), "runs": rates, "stall_s": stall}
