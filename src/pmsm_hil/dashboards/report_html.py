"""`write_report`: a self-contained HTML page comparing runs (metrics table + inline SVG figures)."""

from __future__ import annotations

import html
import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pmsm_hil.dashboards import report_figures as fig
from pmsm_hil.dashboards.errors import DashboardError
from pmsm_hil.dashboards.report_data import RunData, load_run
from pmsm_hil.dashboards.report_end import end_box, no_window_sentence
from pmsm_hil.hil.metrics.registry import REPORT, in_view

#: (header, metrics key, sub-key, format) of the metrics table: the registry's report view.
TABLE = tuple((m.title, m.key, m.sub, "{:" + m.fmt + "}" if m.fmt else "{}") for m in in_view(REPORT))

_CSS = """body{font-family:system-ui,sans-serif;margin:24px;color:#222;max-width:1280px}
h1{font-size:22px}h2{font-size:17px;margin-top:28px;border-bottom:1px solid #ddd}
table{border-collapse:collapse;font-size:13px}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}
th{background:#f3f3f3}td:first-child,th:first-child{text-align:left}.note{color:#666;font-size:12px}
figure{margin:8px 0}svg{max-width:100%;height:auto}
.end{border:2px solid #c0392b;background:#fdecea;padding:8px 12px;margin:12px 0;font-size:14px}"""


def _cell(metrics: dict[str, Any], key: str, sub: str | None, fmt: str) -> str:
    value = metrics.get(key)
    if sub is not None:
        value = value.get(sub) if isinstance(value, dict) else None
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return "–"
    try:
        return html.escape(fmt.format(value))
    except (ValueError, TypeError):
        return html.escape(str(value))


def metrics_table(runs: Sequence[RunData]) -> str:
    """HTML table: one row per metric, one column per run."""
    head = "".join(f"<th>{html.escape(r.label)}</th>" for r in runs)
    rows = [f"<tr><th>metric</th>{head}</tr>"]
    for title, key, sub, fmt in TABLE:
        cells = "".join(f"<td>{_cell(r.metrics, key, sub, fmt)}</td>" for r in runs)
        rows.append(f"<tr><td>{html.escape(title)}</td>{cells}</tr>")
    return "<table id=\"metrics\">" + "".join(rows) + "</table>"


def whole_run_section(runs: Sequence[RunData]) -> list[str]:
    """HTML of the whole-run plots, one figure per run (a sentence for a run that logged no period)."""
    parts = ["<h2>Whole run (every logged period)</h2>"]
    for k, run in enumerate(runs):
        if not run.whole.panels:
            parts.append(f"<p class=\"note\">{html.escape(run.label)}: no period was logged "
                         f"(the run ended {html.escape(run.end.where())}).</p>")
            continue
        marks = (["shaded: the metrics window"] if run.has_window else ["the run never reached its metrics window"])
        if run.end.early and run.end.t_s is not None:
            marks.append(f"dashed red line: the run ended {run.end.where()}")
        parts.append(f"<figure class=\"whole-run\" id=\"whole-run-{k}\">{fig.whole_run(run, f'whole-{k}')}"
                     f"<figcaption class=\"note\">{html.escape(run.label)}: {html.escape(run.whole.note())}; "
                     f"{html.escape('; '.join(marks))}.</figcaption></figure>")
    return parts


def window_sections(runs: Sequence[RunData]) -> list[str]:
    """HTML of the metrics-window charts (bars, waveforms, spectra) of the runs that reached their window;
    a chart no run has data for is replaced by a sentence saying why."""
    with_window = [r for r in runs if r.has_window]
    missing = [no_window_sentence(r.label, r.end) for r in runs if not r.has_window]
    if not with_window:
        return ["<h2>Metrics-window charts</h2>",
                *(f"<p class=\"note no-window\">No metrics-window charts: {html.escape(m)}</p>"
                  for m in missing)]
    parts = [f"<p class=\"note\">Not in the window charts: {html.escape(m)}</p>" for m in missing]
    parts.append("<h2>Torque ripple, current THD, switching frequency, execution time</h2>")
    shown = fig.bar_metrics(with_window)
    if shown:
        parts.append(f"<figure id=\"bars\">{fig.bars(with_window)}</figure>")
    left = [title for _, title, _ in fig.BAR_METRICS if title not in {t for _, t, _ in shown}]
    if left:
        parts.append(f"<p class=\"note\">No value in the metrics window for: {html.escape(', '.join(left))} "
                     "(null in metrics.json, see its notes).</p>")
    parts += ["<h2>Torque and phase currents (last two electrical periods)</h2>",
              f"<figure id=\"waveforms\">{fig.waveforms(with_window)}</figure>",
              "<h2>Harmonic spectrum of i_a</h2>"]
    has_spectrum = [fig.harmonic_spectrum(r)[0].shape[0] > 1 for r in with_window]  # order 2 and up
    if any(has_spectrum):
        spectral = [r for r, ok in zip(with_window, has_spectrum, strict=True) if ok]
        parts.append(f"<figure id=\"spectra\">{fig.spectra(spectral)}</figure>")
    for r, ok in zip(with_window, has_spectrum, strict=True):
        if not ok:
            why = r.metrics.get("current_thd_note") or "the window is shorter than one electrical period"
            parts.append(f"<p class=\"note no-spectrum\">No spectrum for {html.escape(r.label)}: "
                         f"{html.escape(str(why))}.</p>")
    parts.append("<p class=\"note\">THD h2..40: harmonics 2 to 40 of the electrical fundamental; THD all: every "
                 "non-fundamental component (see docs/metrics.md). Spectra are computed here from the logged "
                 "waveform over a whole number of electrical periods.</p>")
    return parts


def render_report(runs: Sequence[RunData], title: str = "PMSM HIL run comparison", *,
                  notes: Sequence[str] = (), generator: str = "hil report", whole_run: bool = False) -> str:
    """The complete HTML document (no external resources); `notes`: extra lines under the header;
    `whole_run`: include the whole-run plots of every run (`hil report`; the compare page leaves them out)."""
    if not runs:
        raise DashboardError("RUN_DIR: at least one run directory is needed")
    sources = "; ".join(f"{html.escape(r.label)}: {html.escape(str(r.path))} ({r.source}, "
                        f"{html.escape(r.metadata.get('motor', '?'))}, Ts = {r.metadata.get('ts_s', '?')} s)"
                        for r in runs)
    parts = [
        "<!DOCTYPE html><html lang=\"en\"><head><meta charset=\"utf-8\">",
        f"<title>{html.escape(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{html.escape(title)}</h1>",
        f"<p class=\"note\">Generated {time.strftime('%Y-%m-%d %H:%M:%S')} by <code>{html.escape(generator)}</code>. "
        f"Runs: {sources}.</p>",
        *(f"<p class=\"note\">{html.escape(line)}</p>" for line in notes),
        *(end_box(r.label, r.end, f"end-{k}") for k, r in enumerate(runs) if r.end.early),
        "<h2>Metrics (metrics window)</h2>", metrics_table(runs),
        *(whole_run_section(runs) if whole_run else []),
        *window_sections(runs),
        "</body></html>",
    ]
    return "\n".join(parts)


def write_report(run_dirs: Sequence[Path], out: Path, title: str = "PMSM HIL run comparison") -> list[RunData]:
    """Load `run_dirs`, write the self-contained HTML report (with the whole-run plots) to `out`; returns
    the runs."""
    runs = [load_run(Path(d)) for d in run_dirs]
    text = render_report(runs, title, whole_run=True)
    try:
        out.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise DashboardError(f"-o {out}: {exc.strerror}") from None
    return runs
