"""The sweep's summary table (printed) and HTML page (report.html: the table, failed runs, and each metric
against each swept numeric variable, one line per controller).

Both group the runs of one configuration (the same point, every repeat) and show the mean over the runs
that completed; a plot against one variable averages over the other swept variables too (its caption
says which), with the min–max range of those runs shaded.
"""

from __future__ import annotations

import html
import math
import time
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from pmsm_hil.dashboards.report_figures import _plt, _svg
from pmsm_hil.dashboards.report_html import _CSS
from pmsm_hil.hil.atomic_write import write_text_atomic
from pmsm_hil.hil.metrics.registry import by_name

#: metrics of the summary table and the plots (registry keys)
SUMMARY_METRICS = ("torque_ripple_rms_nm", "torque_ripple_pp_nm", "current_thd_pct", "switching_freq_khz",
                   "torque_error_mean_nm", "speed_mean_rpm")
#: the column that varies per repeat, never grouped on
_PER_RUN = ("repeat",)


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        return None
    return float(value) if math.isfinite(value) else None


def group_rows(rows: Sequence[Mapping[str, Any]], keys: Sequence[str]) -> list[dict[str, Any]]:
    """One entry per configuration (same `config` text): the key values, `runs`, `failed` and the mean
    of each SUMMARY_METRICS over its completed runs (None when none completed)."""
    groups: dict[str, list[Mapping[str, Any]]] = {}
    for row in rows:
        groups.setdefault(str(row.get("config")), []).append(row)
    out: list[dict[str, Any]] = []
    for members in groups.values():
        entry: dict[str, Any] = {k: members[0].get(k) for k in keys}
        ok = [r for r in members if r.get("end_code") == 0]
        entry["runs"], entry["failed"] = len(members), len(members) - len(ok)
        for metric in SUMMARY_METRICS:
            values = [v for v in (_number(r.get(metric)) for r in ok) if v is not None]
            entry[metric] = sum(values) / len(values) if values else None
        out.append(entry)
    return out


def _key_text(value: Any) -> str:
    """A swept key's value as given (numbers in their shortest form: 3, 4.05)."""
    return f"{value:g}" if isinstance(value, float) else str(value)


def _headers() -> list[str]:
    return [by_name(m).title for m in SUMMARY_METRICS]


def summary_lines(rows: Sequence[Mapping[str, Any]], keys: Sequence[str]) -> list[str]:
    """The printed table: the swept keys, runs, failed and the mean metrics per configuration."""
    keys = [k for k in keys if k not in _PER_RUN]
    head = [*keys, "runs", "failed", *_headers()]
    table = [head]
    for g in group_rows(rows, keys):
        cells = ["-" if g[k] is None else _key_text(g[k]) for k in keys]
        cells += [str(g["runs"]), str(g["failed"])]
        cells += ["-" if g[m] is None else by_name(m).format(g[m]) for m in SUMMARY_METRICS]
        table.append(cells)
    widths = [max(len(r[i]) for r in table) for i in range(len(head))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths, strict=True)).rstrip() for r in table]
    lines.insert(1, "-" * max(len(line) for line in lines))
    return lines


def _numeric_keys(rows: Sequence[Mapping[str, Any]], keys: Sequence[str]) -> list[str]:
    """Swept keys whose every value is a number (plotted on an x axis)."""
    return [k for k in keys if k not in _PER_RUN
            and all(_number(r.get(k)) is not None for r in rows) and len({r.get(k) for r in rows}) > 1]


def _series(rows: Sequence[Mapping[str, Any]], x_key: str, metric: str) -> dict[str, list[tuple[float, float, float,
                                                                                                 float]]]:
    """controller -> [(x, mean, min, max)] over the completed runs at each x."""
    by: dict[str, dict[float, list[float]]] = {}
    for r in rows:
        x, y = _number(r.get(x_key)), _number(r.get(metric))
        if r.get("end_code") != 0 or x is None or y is None:
            continue
        by.setdefault(str(r.get("controller", "all")), {}).setdefault(x, []).append(y)
    return {c: [(x, sum(v) / len(v), min(v), max(v)) for x, v in sorted(pts.items())] for c, pts in by.items()}


def figure(rows: Sequence[Mapping[str, Any]], x_key: str) -> str:
    """SVG: each SUMMARY_METRICS against `x_key`, one line per controller (mean, min–max shaded)."""
    plt = _plt()
    n = len(SUMMARY_METRICS)
    cols = 3
    fig, axes = plt.subplots((n + cols - 1) // cols, cols, figsize=(11, 3.0 * ((n + cols - 1) // cols)),
                             squeeze=False)
    for ax, metric in zip(axes.flat, SUMMARY_METRICS, strict=False):
        for controller, pts in _series(rows, x_key, metric).items():
            xs = [p[0] for p in pts]
            line = ax.plot(xs, [p[1] for p in pts], marker="o", ms=3, lw=1.2, label=controller)[0]
            ax.fill_between(xs, [p[2] for p in pts], [p[3] for p in pts], color=line.get_color(), alpha=0.15, lw=0)
        ax.set_title(by_name(metric).title, loc="left")
        ax.set_xlabel(x_key)
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    fig.tight_layout()
    return _svg(fig)


def _html_table(lines_rows: list[list[str]]) -> str:
    head, *body = lines_rows
    parts = ["<tr>" + "".join(f"<th>{html.escape(c)}</th>" for c in head) + "</tr>"]
    parts += ["<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in row) + "</tr>" for row in body]
    return "<table>" + "".join(parts) + "</table>"


def render_html(rows: Sequence[Mapping[str, Any]], keys: Sequence[str], *, title: str,
                notes: Sequence[str] = ()) -> str:
    """The complete self-contained page."""
    group_keys = [k for k in keys if k not in _PER_RUN]
    table = [[*group_keys, "runs", "failed", *_headers()]]
    for g in group_rows(rows, group_keys):
        table.append([*("–" if g[k] is None else _key_text(g[k]) for k in group_keys), str(g["runs"]), str(g["failed"]),
                      *("–" if g[m] is None else by_name(m).format(g[m]) for m in SUMMARY_METRICS)])
    failed = [r for r in rows if r.get("end_code") != 0]
    parts = [
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">",
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        f"<p class=\"note\">Generated {time.strftime('%Y-%m-%d %H:%M:%S')} by <code>hil sweep</code>: "
        f"{len(rows)} runs, {len(failed)} did not complete. Means over the completed runs of each "
        "configuration (every repeat).</p>",
        *(f"<p class=\"note\">{html.escape(line)}</p>" for line in notes),
        "<h2>Summary</h2>", _html_table(table),
    ]
    numeric = _numeric_keys(rows, keys)
    for x_key in numeric:
        others = [k for k in group_keys if k not in (x_key, "controller")]
        caption = (f"Mean over the other swept variables ({', '.join(others)}) and the repeats; shaded: min–max."
                   if others else "Mean over the repeats; shaded: min–max.")
        parts += [f"<h2>Metrics against {html.escape(x_key)}</h2>",
                  f"<figure id=\"vs-{html.escape(x_key)}\">{figure(rows, x_key)}"
                  f"<figcaption class=\"note\">{html.escape(caption)}</figcaption></figure>"]
    if not numeric:
        parts.append("<p class=\"note\">No numeric swept variable: no plot (the table above has every figure).</p>")
    if failed:
        parts += ["<h2>Runs that did not complete</h2>",
                  _html_table([["run id", "end code", "end reason", "configuration"]]
                              + [[str(r.get("run_id")), str(r.get("end_code")), str(r.get("end_reason")),
                                  str(r.get("config"))] for r in failed])]
    parts.append("</body></html>")
    return "\n".join(parts)


def write_html(path: Path, rows: Sequence[Mapping[str, Any]], keys: Sequence[str], *, title: str,
               notes: Sequence[str] = ()) -> Path:
    """Write the page through a temporary file; returns `path`."""
    write_text_atomic(path, render_html(rows, keys, title=title, notes=notes), option="--out")
    return path


__all__ = ["SUMMARY_METRICS", "figure", "group_rows", "render_html", "summary_lines", "write_html"]
