"""`hil run`'s status line: the run's phase (starting the target, configuring it, running, writing the outputs)
and, block by block while it runs, periods done / total, simulated time, the rate, the speed and torque so far,
and the real-time deadline flags as warnings when they first appear (app/cli/status_line.py draws it)."""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from pmsm_hil.app.cli.status_line import StatusLine
from pmsm_hil.hil.runner.run_config import RunConfig

_RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)


def target_name(cfg: RunConfig) -> str:
    """How the status line names the run's target: `qemu:fw.elf`, `sil:libfw.so`, `spawn` ..."""
    target = cfg.target
    if ":" in target and cfg.target_path is not None:
        return f"{target.split(':', 1)[0]}:{Path(str(cfg.target_path)).name}"
    return target


class RunStatus:
    """Feeds a `StatusLine` from `run_closed_loop`'s phases (`phase`) and period blocks (`block`)."""

    def __init__(self, line: StatusLine, cfg: RunConfig) -> None:
        self.line = line
        self.ts_s = cfg.ts_s
        self.total = round(cfg.scenario.total_s / cfg.ts_s)
        self.done = 0  # periods run (the live counter, or the records seen)
        self.seen = 0  # period records drained
        self.late = self.missed = 0
        self.speed_rpm = self.torque_nm = math.nan
        self._t_run: float | None = None
        self._counter: Callable[[], int] | None = None
        line.phase(f"starting target {target_name(cfg)}…")

    def phase(self, name: str) -> None:
        """A phase of `run_closed_loop` (`configuring target`, `running`, `writing outputs`)."""
        self.line.phase(name)
        if name == "running":
            self._t_run = time.monotonic()
            self.line.total(self.total, "periods")

    def counter(self, periods_run: Callable[[], int]) -> None:
        """The loop's live period counter (`run_closed_loop(counter=...)`): read at each redraw, so the count moves
        between blocks (a slow target's block of ~1000 periods takes seconds)."""
        self._counter = periods_run
        self.line.poll = self._poll

    def _poll(self) -> None:
        if self._counter is None:
            return
        done = min(int(self._counter()), self.total)
        if done > self.done:
            self.done = done
            self.line.update(done, self.figures())

    def block(self, periods: np.ndarray) -> None:
        """One block of period records (PERIOD_DTYPE) the loop has run."""
        n = int(periods.shape[0])
        if not n:
            return
        if self._t_run is None:
            self.phase("running")
        self.seen += n
        self.done = max(self.done, self.seen)
        self._warn_deadlines(periods)
        self.speed_rpm = float(periods["omega_m"][-1]) * _RAD_S_TO_RPM
        self.torque_nm = float(np.nanmean(periods["torque"]))
        self.line.update(self.done, self.figures())

    def figures(self) -> str:
        """The right-hand side: simulated time, rate and its ratio to real time, speed and torque so far (those of
        the last block drained)."""
        sim_s = self.done * self.ts_s
        wall_s = time.monotonic() - (self._t_run or time.monotonic())
        rate = self.done / wall_s if wall_s > 0 else 0.0
        speed, torque = self.speed_rpm, self.torque_nm
        machine = f", {speed:.0f} rpm, {torque:.2f} N·m" if math.isfinite(speed) and math.isfinite(torque) else ""
        flags = "".join(f", {k} {label}" for k, label in ((self.late, "late"), (self.missed, "missed")) if k)
        return (f"sim {sim_s:.3f}/{self.total * self.ts_s:.3f} s, {_rate(rate)} periods/s "
                f"({rate * self.ts_s:.2f}× real time){machine}{flags}")

    def _warn_deadlines(self, periods: np.ndarray) -> None:
        first = self.seen - int(periods.shape[0])
        for field, what in (("late", "started late"), ("missed", "missed its deadline")):
            flags = np.flatnonzero(periods[field])
            if not flags.size:
                continue
            before = getattr(self, field)
            setattr(self, field, before + int(flags.size))
            if not before:
                self.line.warn(f"real time: period {first + int(flags[0])} {what} (counted in the metrics; "
                               f"the status line shows the count)")


def _rate(per_s: float) -> str:
    return f"{per_s / 1e3:.1f}k" if per_s >= 1e4 else f"{per_s:.0f}"


__all__ = ["RunStatus", "target_name"]
