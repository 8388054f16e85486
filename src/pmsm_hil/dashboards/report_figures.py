"""Figures of the HTML report (matplotlib, Agg) as inline SVG text."""

from __future__ import annotations

import io
import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from pmsm_hil.dashboards.report_data import RunData
from pmsm_hil.dashboards.report_whole_run import WholeRun
from pmsm_hil.hil.metrics.registry import REPORT_BARS, in_view

#: Harmonic orders shown in the spectra.
MAX_ORDER = 40


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams.update({"font.size": 9, "axes.grid": True, "grid.alpha": 0.3, "svg.fonttype": "none"})
    return plt


def _svg(fig: Any) -> str:
    buf = io.StringIO()
    fig.savefig(buf, format="svg", bbox_inches="tight")
    _plt().close(fig)
    text = buf.getvalue()
    return text[text.index("<svg"):]


def _last_periods(run: RunData, periods: float = 2.0) -> np.ndarray:
    """Mask of the last `periods` electrical periods of the run's waveform."""
    f1 = run.fundamental_hz
    span = periods / f1 if f1 > 0 and math.isfinite(f1) else 0.05
    return np.asarray(run.t >= run.t[-1] - span)


def waveforms(runs: Sequence[RunData]) -> str:
    """Torque with its reference and the phase currents, last two electrical periods, one row per run."""
    plt = _plt()
    fig, axes = plt.subplots(len(runs), 2, figsize=(10, 2.3 * len(runs)), squeeze=False)
    for row, run in zip(axes, runs, strict=True):
        m = _last_periods(run)
        t_ms = (run.t[m] - run.t[m][0]) * 1e3
        row[0].plot(t_ms, run.torque[m], lw=0.8, label="torque")
        row[0].plot(t_ms, run.torque_ref[m], lw=1.0, ls="--", label="reference")
        row[0].set_ylabel("T [N·m]")
        row[0].set_title(run.label, loc="left")
        row[0].legend(loc="lower right", fontsize=7)
        for k, name in enumerate(("i_a", "i_b", "i_c")):
            row[1].plot(t_ms, run.currents[k][m], lw=0.8, label=name)
        row[1].set_ylabel("i [A]")
        row[1].legend(loc="lower right", fontsize=7, ncol=3)
    for ax in axes[-1]:
        ax.set_xlabel("t [ms]")
    fig.tight_layout()
    return _svg(fig)


def harmonic_spectrum(run: RunData) -> tuple[np.ndarray, np.ndarray]:
    """(orders 1..MAX_ORDER, amplitude [% of fundamental]) of i_a over a whole number of electrical periods,
    resampled uniformly (the trace step is not exactly constant)."""
    f1 = run.fundamental_hz
    if not (f1 > 0 and math.isfinite(f1)):
        return np.zeros(0), np.zeros(0)
    span = run.t[-1] - run.t[0]
    periods = math.floor(span * f1)
    if periods < 1:
        return np.zeros(0), np.zeros(0)
    dt = float(np.median(np.diff(run.t)))
    n = round(periods / f1 / dt)
    t = run.t[-1] - periods / f1 + np.arange(n) * (periods / f1 / n)
    x = np.interp(t, run.t, run.currents[0])
    amp = np.abs(np.fft.rfft(x)) * 2.0 / n
    orders = np.arange(1, MAX_ORDER + 1)
    idx = orders * periods
    idx = idx[idx < amp.shape[0]]
    if idx.shape[0] == 0 or amp[idx[0]] == 0.0:
        return np.zeros(0), np.zeros(0)
    return orders[: idx.shape[0]], 100.0 * amp[idx] / amp[idx[0]]


def spectra(runs: Sequence[RunData]) -> str:
    """Harmonic spectra of i_a (orders 2..40, % of the fundamental), grouped bars per order."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(10, 3.0))
    width = 0.8 / max(len(runs), 1)
    for k, run in enumerate(runs):
        orders, pct = harmonic_spectrum(run)
        keep = orders >= 2
        thd = run.metrics.get("current_thd_pct")
        thd_text = f"{thd:.2f} %" if isinstance(thd, int | float) else "n/a"  # null: window too short for a THD
        ax.bar(orders[keep] - 0.4 + (k + 0.5) * width, pct[keep], width=width,
               label=f"{run.label} (THD {thd_text})")
    ax.set_xlabel("harmonic order of i_a")
    ax.set_ylabel("amplitude [% of fundamental]")
    ax.set_xlim(1.4, MAX_ORDER + 0.6)
    ax.legend(fontsize=7)
    fig.tight_layout()
    return _svg(fig)


#: (key, title, sub-key) of the bar charts: the registry's report-bars view.
BAR_METRICS = tuple((m.key, m.title, m.sub) for m in in_view(REPORT_BARS))


def _metric(run: RunData, key: str, sub: str | None) -> float:
    value = run.metrics.get(key)
    if sub is not None and isinstance(value, dict):
        value = value.get(sub)
    return float(value) if isinstance(value, (int, float)) else math.nan


def bar_metrics(runs: Sequence[RunData]) -> tuple[tuple[str, str, str | None], ...]:
    """The bar charts with a value for at least one run (a chart without any would be empty)."""
    return tuple(b for b in BAR_METRICS if any(math.isfinite(_metric(r, b[0], b[2])) for r in runs))


def bars(runs: Sequence[RunData]) -> str:
    """Bar charts of ripple, THD, f_av and execution time per run (those of `bar_metrics`; at least one)."""
    plt = _plt()
    shown = bar_metrics(runs)
    fig, axes = plt.subplots(1, len(shown), figsize=(3.0 * len(shown), 3.0), squeeze=False)
    labels = [r.label.split(" · ")[0] for r in runs]
    colors = [f"C{k % 10}" for k in range(len(runs))]
    for ax, (key, title, sub) in zip(axes[0], shown, strict=True):
        values = [_metric(r, key, sub) for r in runs]
        ax.bar(range(len(runs)), values, color=colors)
        ax.set_xticks(range(len(runs)), labels, rotation=30, ha="right")
        ax.set_title(title)
        for x, v in enumerate(values):
            if math.isfinite(v):
                ax.annotate(f"{v:.3g}", (x, v), ha="center", va="bottom", fontsize=7)
    fig.tight_layout()
    return _svg(fig)


def whole_run(run: RunData, gid: str) -> str:
    """The whole run, one panel per `WholeRun` panel on a shared time axis: the metrics window shaded, the
    end of a run that ended early marked; the decimation is said in the title. Line `gid`s (SVG ids):
    `{gid}-{panel}-{trace}` (indices) and `{gid}-{panel}-end` (the end mark), for tests."""
    plt = _plt()
    w: WholeRun = run.whole
    scale, unit = (1.0, "s") if w.t_stop_s > 1.0 else (1e3, "ms")
    fig, axes = plt.subplots(len(w.panels), 1, figsize=(10, 1.7 * len(w.panels) + 0.6), sharex=True,
                             squeeze=False)
    window = run.end.window_periods
    t_window = float(run.t[0]) if run.has_window else None
    for k, (ax, panel) in enumerate(zip(axes[:, 0], w.panels, strict=True)):
        for j, tr in enumerate(panel.traces):
            (line,) = ax.plot(tr.t * scale, tr.y, lw=0.7, label=tr.label)
            line.set_gid(f"{gid}-{k}-{j}")
        if t_window is not None:
            ax.axvspan(t_window * scale, w.t_stop_s * scale, color="tab:green", alpha=0.08,
                       label=f"metrics window ({window} periods)" if k == 0 else None)
        if run.end.early and run.end.t_s is not None:
            mark = ax.axvline(run.end.t_s * scale, color="tab:red", lw=1.2, ls="--",
                              label=f"run ended {run.end.where()}" if k == 0 else None)
            mark.set_gid(f"{gid}-{k}-end")
        ax.set_ylabel(panel.ylabel)
        ax.set_title(panel.title, loc="left", fontsize=8)
        ax.legend(loc="upper right", fontsize=7, ncol=4)
    axes[-1, 0].set_xlabel(f"t [{unit}]")
    fig.suptitle(f"{run.label}: {w.note()}", fontsize=9)
    fig.tight_layout()
    return _svg(fig)
