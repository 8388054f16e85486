"""PNG figures of a comparison (matplotlib, Agg backend): the analogue of the paper's figure."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from pmsm_hil.app.compare.runs import CompareResult
from pmsm_hil.app.compare.spread import aggregate
from pmsm_hil.hil.errors import InputFileError
from pmsm_hil.hil.metrics.registry import COMPARE_BARS, in_view


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _main_rows(result: CompareResult) -> list[dict[str, Any]]:
    return [r for r in result.rows if r["group"] == "main"]


def _bars(result: CompareResult, plt: Any) -> Any:
    rows = result.rows
    labels = [(r.get("label") or r["controller"]) + ("\n(eq. f_av)" if r["group"] == "equal_fav" else "")
              for r in rows]
    metrics = [(m.key, m.title) for m in in_view(COMPARE_BARS)]
    fig, axes = plt.subplots(1, len(metrics), figsize=(4.2 * len(metrics), 4.2))
    x = list(range(len(rows)))
    for ax, (key, title) in zip(axes, metrics, strict=True):
        ax.bar(x, [r.get(key) or 0.0 for r in rows], color="tab:blue")
        ax.set_xticks(x, labels, rotation=60, fontsize=8)
        ax.set_title(title, fontsize=10)
        ax.grid(axis="y", alpha=0.3)
    paper_keys = {"torque_ripple_rms_nm": "torque_ripple_nm", "current_thd_pct": "current_thd_pct"}
    for ax, (metric, _) in zip(axes, metrics, strict=True):  # the paper's figures beside ours
        paper_key = paper_keys.get(metric)
        if paper_key is None:
            continue
        marked = False
        for i, r in enumerate(rows):
            val = result.preset.paper.get(r.get("label") or r["controller"], {}).get(paper_key)
            if val is not None and r["group"] == "main":
                ax.plot(i, val, "r*", markersize=11, label=None if marked else "paper (experiment)")
                marked = True
        if marked:
            ax.legend(fontsize=8)
    return fig


def _sweep(result: CompareResult, plt: Any, key: str, ylabel: str, xkey: str, xlabel: str,
           xscale: float = 1.0) -> Any:
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    agg = [r for r in aggregate(result.rows) if r["group"] == "main"]  # means over the initial rotor angles
    names = list(dict.fromkeys(r["label"] for r in agg))
    for name in names:
        rows = [r for r in agg if r["label"] == name]
        ax.plot([r[xkey] * xscale for r in rows],
                [math.nan if r.get(key) is None else r[key] for r in rows], "o-", label=name)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return fig


def _accel(result: CompareResult, plt: Any) -> Any:
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
    for name, s in result.series.items():
        a1.plot(s["t"], s["speed_rpm"], label=name, lw=1)
        a2.plot(s["t"], s["torque_nm"], label=name, lw=0.6)
    a1.set_ylabel("speed [rpm]")
    a2.set_ylabel("torque [N·m]")
    a2.set_xlabel("t [s]")
    a1.grid(alpha=0.3)
    a2.grid(alpha=0.3)
    a1.legend(fontsize=8)
    return fig


def write_png(result: CompareResult, path: Path) -> bool:
    """Write the preset's figure; False when the preset has none."""
    kind = result.preset.figure
    if kind == "none":
        return False
    plt = _pyplot()
    if kind == "bars":
        fig = _bars(result, plt)
    elif kind == "thd_vs_load":
        rated = max(r["load_nm"] for r in result.rows) or 1.0
        fig = _sweep(result, plt, "current_thd_pct", "current THD h2-40 [%]", "load_nm", "load [% of max]",
                     100.0 / rated)
    elif kind == "ripple_vs_speed":
        fig = _sweep(result, plt, "torque_ripple_rms_nm", "torque ripple RMS [N·m]", "speed_rpm", "speed [rpm]")
    else:
        fig = _accel(result, plt)
    fig.suptitle(f"hil compare --preset {result.preset.name}", fontsize=10)
    save_figure(plt, fig, path, 110, f"png file {path}")
    return True


def save_figure(plt: Any, fig: Any, path: Path, dpi: int, field: str) -> None:
    """Lay out `fig`, write it to `path` at `dpi` and close it; a write that fails is InputFileError naming
    `field`."""
    fig.tight_layout()
    try:
        fig.savefig(path, dpi=dpi)
    except OSError as exc:
        raise InputFileError(f"{field}: {exc.strerror}") from None
    finally:
        plt.close(fig)
