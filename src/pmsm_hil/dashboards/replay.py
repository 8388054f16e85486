"""Replay a recorded run (our MCAP) into the live dashboard's Rerun blueprint."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pmsm_hil.dashboards.blueprint import build_blueprint
from pmsm_hil.dashboards.errors import DashboardError
from pmsm_hil.dashboards.recording import RerunTargets, flush_recording, open_recording
from pmsm_hil.dashboards.streamer import PeriodStreamer
from pmsm_hil.hil.errors import HilError
from pmsm_hil.hil.machine import layout_for_phases, load_machine
from pmsm_hil.hil.runlog.reader import ScanState, read_metadata, read_periods

BLOCK = 1000


@dataclass(frozen=True)
class ReplaySource:
    """What the dashboard needs from a run: the period records, Vdc [V], Ts [s], phases and a name."""

    periods: Any
    vdc: float
    ts_s: float
    phases: int
    name: str


def load_source(path: Path, *, vdc: float | None = None) -> ReplaySource:
    """Period records and run facts of `path` (Vdc from the motor preset named in the metadata unless given)."""
    if not path.is_file():
        raise DashboardError(f"RUN.mcap: {path} is not a file")
    meta = read_metadata(path)
    state = ScanState()
    periods = read_periods(path, state)
    if not state.complete:
        raise DashboardError(f"RUN.mcap: {path} is {state.cut_reason(path, 'replay')}")
    if len(periods) == 0:
        raise DashboardError(f"RUN.mcap: {path} holds no /periods messages")
    try:
        ts_s = float(meta["ts_s"]) if "ts_s" in meta else float(periods["t"][1] - periods["t"][0])
    except (ValueError, IndexError):
        raise DashboardError(f"RUN.mcap: metadata ts_s {meta.get('ts_s')!r} is not a number") from None
    phases: int | None = None
    if "phases" in meta:
        try:
            phases = layout_for_phases(int(meta["phases"])).legs
        except (ValueError, HilError):
            raise DashboardError(f"RUN.mcap: metadata phases {meta['phases']!r} is not a known phase count") from None
    motor_vdc: float | None = None
    if "motor" in meta:
        try:
            machine = load_machine(meta["motor"])
            motor_vdc = machine.params.vdc
            phases = machine.phases if phases is None else phases  # logs written before the phases key
        except HilError:
            motor_vdc = None
    if vdc is None:
        vdc = motor_vdc
    if vdc is None or not vdc > 0.0:
        raise DashboardError(f"--vdc: the run's motor {meta.get('motor')!r} is unknown here; give --vdc in V")
    name = " ".join(meta[k] for k in ("motor", "controller", "scenario") if k in meta) or path.stem
    return ReplaySource(periods, float(vdc), ts_s, 3 if phases is None else phases, name)


def replay_to_rerun(source: ReplaySource, targets: RerunTargets,
                    progress: Callable[[np.ndarray], None] | None = None) -> tuple[Any, str | None]:
    """Send all periods of `source` to `targets`; returns (recording stream, web URL or None), flushed.
    `progress` is given each block once sent (a status line)."""
    rec, url = open_recording(targets, build_blueprint(phases=source.phases, vdc=source.vdc))
    rec.send_recording_name(source.name)
    streamer = PeriodStreamer(rec, vdc=source.vdc, ts_s=source.ts_s, legs=source.phases)
    for start in range(0, len(source.periods), BLOCK):
        block = source.periods[start:start + BLOCK]
        streamer.send_block(block)
        if progress is not None:
            progress(block)
    flush_recording(rec)
    return rec, url
