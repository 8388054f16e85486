"""Whole-run series of the HTML report: every logged period, min/max-decimated to a bounded size."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from pmsm_hil.dashboards.decimate import minmax_decimate

#: Most points drawn per trace of a whole-run plot (min and max of MAX_POINTS_PER_TRACE // 2 buckets).
MAX_POINTS_PER_TRACE = 2000

_RPM_PER_RAD_S = 60.0 / (2.0 * math.pi)

#: (panel title, y label, ((trace label, PERIOD_DTYPE field, scale), ...)); panels with no finite sample are
#: left out (the second set of a three-phase run).
PANELS: tuple[tuple[str, str, tuple[tuple[str, str, float], ...]], ...] = (
    ("speed", "n [rpm]", (("speed", "omega_m", _RPM_PER_RAD_S), ("reference", "speed_ref", _RPM_PER_RAD_S))),
    ("torque", "T [N·m]", (("torque", "torque", 1.0), ("reference", "torque_ref", 1.0),
                           ("load", "load_torque", 1.0))),
    ("phase currents", "i [A]", (("i_a", "i_a", 1.0), ("i_b", "i_b", 1.0), ("i_c", "i_c", 1.0))),
    ("phase currents, second set", "i [A]", (("i_u", "i_u", 1.0), ("i_v", "i_v", 1.0), ("i_w", "i_w", 1.0))),
    ("dq currents", "i [A]", (("i_d", "i_d", 1.0), ("i_q", "i_q", 1.0))),
)


@dataclass(frozen=True, slots=True)
class Trace:
    """One decimated trace: label, time [s], values (panel unit)."""

    label: str
    t: np.ndarray
    y: np.ndarray


@dataclass(frozen=True, slots=True)
class Panel:
    """One whole-run plot: title, y label, its traces."""

    title: str
    ylabel: str
    traces: tuple[Trace, ...]


@dataclass(frozen=True, slots=True)
class WholeRun:
    """The whole run for plotting: periods logged, their time span [s], the decimated panels, the bound."""

    periods: int
    t_start_s: float
    t_stop_s: float
    panels: tuple[Panel, ...]
    max_points: int

    @property
    def decimated(self) -> bool:
        """True when a trace had more samples than `max_points`."""
        return self.periods > self.max_points

    def note(self) -> str:
        """What the plot shows, in words (periods, decimation)."""
        if not self.decimated:
            return f"all {self.periods} periods (no decimation)"
        return (f"{self.periods} periods, decimated: min and max of {self.max_points // 2} buckets "
                f"(≤ {self.max_points} points per trace)")


def whole_run(periods: np.ndarray, max_points: int = MAX_POINTS_PER_TRACE) -> WholeRun:
    """`WholeRun` of a PERIOD_DTYPE array (any length, also empty)."""
    t = np.asarray(periods["t"], dtype=float)
    panels = []
    for title, ylabel, fields in PANELS:
        traces = []
        for label, name, scale in fields:
            y = np.asarray(periods[name], dtype=float) * scale
            if np.isfinite(y).any():
                traces.append(Trace(label, *minmax_decimate(t, y, max_points)))
        if traces:
            panels.append(Panel(title, ylabel, tuple(traces)))
    span = (float(t[0]), float(t[-1])) if len(t) else (0.0, 0.0)
    return WholeRun(len(t), span[0], span[1], tuple(panels), max_points)
