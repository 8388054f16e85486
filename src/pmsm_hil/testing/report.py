"""Failure plots: a PNG of the signal with its band, written under the test's output folder and recorded in the
JUnit XML (`record_property("hil_plot", path)`), plus a `[[ATTACHMENT|path]]` line on stdout for CI systems that
read attachments from the captured output (GitLab, Jenkins; with `-o junit_logging=system-out`)."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pmsm_hil.testing.signals import Signal

#: JUnit XML property holding the path of a failure plot
PLOT_PROPERTY = "hil_plot"


@dataclass(frozen=True, slots=True)
class PlotRequest:
    """What the plot shows besides the signal: the band [lo, hi] (infinite/NaN ends are not drawn), the checked
    window [t0, t1] [s] (None: open), the worst violation (t [s], value) and a title."""

    lo: float = math.nan
    hi: float = math.nan
    t0: float | None = None
    t1: float | None = None
    worst: tuple[float, float] | None = None
    title: str = ""


class Reporter:
    """Writes failure plots of one test under `out_dir` and records their paths with `record_property`."""

    def __init__(self, out_dir: Path,
                 record_property: Callable[[], Callable[[str, object], None]] | None = None) -> None:
        """`record_property`: gives pytest's `record_property` when a plot is written (requested only then:
        the fixture warns under the xunit2 JUnit family, which still writes the property)."""
        self.out_dir = out_dir
        self.record_property = record_property
        self.plots: list[Path] = []

    def plot(self, assertion: str, sig: Signal, req: PlotRequest) -> Path:
        """Write the PNG (a unique name from the assertion and the signal), record it, return its path."""
        self.out_dir.mkdir(parents=True, exist_ok=True)
        stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", f"{assertion}-{sig.name}")
        path = self.out_dir / f"{stem}.png"
        n = 2
        while path.exists() or path in self.plots:
            path, n = self.out_dir / f"{stem}-{n}.png", n + 1
        write_plot(path, assertion, sig, req)
        path = path.resolve()
        self.plots.append(path)
        if self.record_property is not None:
            self.record_property()(PLOT_PROPERTY, str(path))
        print(f"[[ATTACHMENT|{path}]]")
        return path


def write_plot(path: Path, assertion: str, sig: Signal, req: PlotRequest) -> None:
    """The signal over time, its band shaded over the checked window, the worst violation marked. A bare Figure
    renders through matplotlib's Agg canvas whatever backend the session selected (pyplot is not touched)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.0, 3.6), dpi=100, layout="constrained")
    ax = fig.add_subplot()
    ax.plot(sig.t, sig.y, lw=0.8, color="C0", label=sig.name)
    if len(sig):
        t0 = float(sig.t[0]) if req.t0 is None else req.t0
        t1 = float(sig.t[-1]) if req.t1 is None else req.t1
        lo = req.lo if math.isfinite(req.lo) else None
        hi = req.hi if math.isfinite(req.hi) else None
        if lo is not None and hi is not None:
            ax.fill_between([t0, t1], lo, hi, color="C2", alpha=0.2, label="band")
        for edge in (lo, hi):
            if edge is not None:
                ax.hlines(edge, t0, t1, colors="C2", lw=1.0, linestyles="--")
        ax.axvspan(t0, t1, color="0.9", zorder=0, label="checked window")
    if req.worst is not None:
        ax.plot(*req.worst, "x", color="C3", ms=9, mew=2,
                label=f"worst {req.worst[1]:.4g} at {req.worst[0]:.4g} s")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(f"{sig.name} [{sig.unit}]" if sig.unit else sig.name)
    ax.set_title(f"{assertion}: {sig.name}" + (f" — {req.title}" if req.title else ""), fontsize=10)
    ax.grid(True, lw=0.3)
    ax.legend(fontsize=8, loc="best")
    tmp = path.with_name(path.name + ".tmp")
    fig.savefig(tmp, format="png")
    tmp.replace(path)


_active: list[Reporter] = []


def active_reporter() -> Reporter | None:
    """The report of the running test that uses the `hil` fixture (None outside one)."""
    return _active[-1] if _active else None


def push_reporter(reporter: Reporter) -> None:
    """Make `reporter` the active one (the `hil` fixture, for the duration of its test)."""
    _active.append(reporter)


def pop_reporter(reporter: Reporter) -> None:
    """Undo `push_reporter`."""
    if reporter in _active:
        _active.remove(reporter)


__all__ = ["PLOT_PROPERTY", "PlotRequest", "Reporter", "active_reporter", "pop_reporter", "push_reporter",
           "write_plot"]
