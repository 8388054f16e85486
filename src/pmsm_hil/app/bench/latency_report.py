"""The OSADL-style latency report of `hil bench realtime --histogram PREFIX`: PREFIX.csv (period starts per 1 µs
lateness bin, one column per measured series) and PREFIX.png (the same as curves on a log-scale count axis, the
maximum of each series in its legend, the load in the title), to attach to a test report."""

from __future__ import annotations

import csv
import io
import platform
from pathlib import Path
from typing import Any

from pmsm_hil.hil.atomic_write import atomic_path, ensure_dir, write_text_atomic


def series(figures: dict[str, Any]) -> dict[str, tuple[list[int], float]]:
    """`{name: (counts per 1 µs bin, maximum [µs])}` of every measured (Ts, link, loop) with a C-loop lateness
    histogram (e.g. 'Ts 25 µs inproc native'), and of each Ts's floor: the gaps between two clock reads of the
    bare C busy loop (almost all in bin 0; the bins from 1 µs on are what the machine takes away)."""
    out: dict[str, tuple[list[int], float]] = {}
    for point in figures["points"]:
        ts = f"Ts {point['ts_s'] * 1e6:g} µs"
        for link, loops in point.items():
            if not isinstance(loops, dict) or link == "floor":
                continue
            for loop, f in loops.items():
                if isinstance(f, dict) and f.get("histogram_1us") is not None:
                    out[f"{ts} {link} {loop}"] = (f["histogram_1us"], f["lateness_max_us"])
        floor = point.get("floor")
        if floor is not None:
            out[f"{ts} floor (bare C busy loop, gaps)"] = (floor["histogram_1us"], floor["max_gap_us"])
    return out


def histogram_csv(data: dict[str, tuple[list[int], float]]) -> str:
    """CSV text: `bin_start_us, bin_end_us, <series>...`; the last bin is open-ended (bin_end_us empty)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    names = list(data)
    w.writerow(["bin_start_us", "bin_end_us", *names])
    n_bins = max((len(c) for c, _ in data.values()), default=0)
    for i in range(n_bins):
        w.writerow([i, "" if i == n_bins - 1 else i + 1, *(data[n][0][i] for n in names)])
    return buf.getvalue()


def _title(figures: dict[str, Any], load_line: str | None) -> str:
    load = figures["load_average_1min"]
    prio = f"SCHED_FIFO {figures['rt_priority']}" if figures["rt_priority"] else "normal priority"
    return (f"{platform.node()} ({platform.release()}): lateness of the period starts, {figures['repeats']} × "
            f"{figures['duration_s']:g} s per series, {prio}\nload average (1 min) {load['min']:.2f}..{load['max']:.2f}"
            + (f"; {load_line}" if load_line else ""))


def histogram_png(path: Path, figures: dict[str, Any], data: dict[str, tuple[list[int], float]],
                  load_line: str | None) -> None:
    """The histogram as curves: x lateness [µs] (1 µs bins), y period starts (log scale)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(10, 5.5))
    top = 1
    for name, (counts, max_us) in data.items():
        last = max((i for i, c in enumerate(counts) if c), default=0)
        top = max(top, last + 2)
        x = list(range(last + 2))
        ax.step(x, [*counts[: last + 1], 0], where="post", label=f"{name} (max {max_us:.1f} µs)",
                linestyle=":" if "floor" in name else "-")
    ax.set_yscale("log")
    ax.set_xlim(0, top)
    ax.set_ylim(0.8, None)
    ax.set_xlabel("lateness [µs] (1 µs bins; the last bin is 1023 µs and more)")
    ax.set_ylabel("period starts (floor: clock reads)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(_title(figures, load_line), fontsize=9)
    fig.tight_layout()
    with atomic_path(path, option="--histogram") as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)


def write_report(prefix: Path, figures: dict[str, Any], load_line: str | None) -> tuple[Path, Path]:
    """PREFIX.csv and PREFIX.png (the folder is created); returns both paths."""
    data = series(figures)
    ensure_dir(prefix.parent, option="--histogram")
    csv_path = prefix.with_name(prefix.name + ".csv")
    png_path = prefix.with_name(prefix.name + ".png")
    write_text_atomic(csv_path, histogram_csv(data), option="--histogram")
    histogram_png(png_path, figures, data, load_line)
    return csv_path, png_path
