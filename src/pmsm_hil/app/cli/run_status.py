"""`hil run`'s status line: the run's phase (starting the target, configuring it, running, writing the outputs)
and, block by block while it runs, periods done / total, simulated time, the rate, the speed and torque so far,
and the real-time deadline flags as warnings when they first appear (app/cli/status_line.py draws it)."""

from __future__ import annotations

import math
import time
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
        self.done = 0
        self.late = self.missed = 0
        self._t_run: float | None = None
        line.phase(f"starting target {target_name(cfg)}…")

    def phase(self, name: str) -> None:
        """A phase of `run_closed_loop` (`configuring target`, `running`, `writing outputs`)."""
        self.line.phase(name)
        if name == "running":
            self._t_run = time.monotonic()
            self.line.total(self.total, "periods")

    def block(self, periods: np.ndarray) -> None:
        """One block of period records (PERIOD_DTYPE) the loop has run."""
        n = int(periods.shape[0])
        if not n:
            return
        if self._t_run is None:
            self.phase("running")
        self.done += n
        self._warn_deadlines(periods)
        self.line.update(self.done, self.figures(periods))

    def figures(self, periods: np.ndarray) -> str:
        """The right-hand side: simulated time, rate and its ratio to real time, speed and torque so far."""
        sim_s = self.done * self.ts_s
        wall_s = time.monotonic() - (self._t_run or time.monotonic())
        rate = self.done / wall_s if wall_s > 0 else 0.0
        speed = float(periods["omega_m"][-1]) * _RAD_S_TO_RPM
        torque = float(np.nanmean(periods["torque"]))
        flags = "".join(f", {k} {label}" for k, label in ((self.late, "late"), (self.missed, "missed")) if k)
        return (f"sim {sim_s:.3f}/{self.total * self.ts_s:.3f} s, {_rate(rate)} periods/s "
                f"({rate * self.ts_s:.2f}× real time), {speed:.0f} rpm, {torque:.2f} N·m{flags}")

    def _warn_deadlines(self, periods: np.ndarray) -> None:
        first = self.done - int(periods.shape[0])
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
