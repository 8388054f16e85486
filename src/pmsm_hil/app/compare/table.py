"""Comparison table: text (with the paper's figures beside ours), JSON and CSV."""

from __future__ import annotations

import csv
import json
import textwrap
from pathlib import Path
from typing import Any

from pmsm_hil.app.compare.runs import CompareResult
from pmsm_hil.app.compare.spread import aggregate
from pmsm_hil.hil.errors import InputFileError
from pmsm_hil.hil.metrics.registry import row_keys

#: widest line of the printed table [characters]
TABLE_WIDTH = 120
#: CSV columns: the operating point, every compare-row metric of the registry, how the run ended
COLUMNS = ("group", "controller", "ts_us", "speed_rpm", "load_nm", *row_keys(), "end_reason", "label",
           "theta0_rad")
_HEAD = ("controller", "Ts µs", "rpm", "N·m", "ripple rms", "ripple p-p", "THD 2-40 %", "THD all %",
         "f_av kHz", "f_av intra", "narrow req/gated", "E", "cand", "T err N·m", "miss rate", "t98 s", "runs",
         "x-y rms A", "dist rms A", "trips", "paper")


def _fmt(value: Any, spec: str) -> str:
    if value is None:
        return "-"
    if isinstance(value, float | int):
        return format(value, spec)
    return str(value)


def _paper(result: CompareResult, controller: str) -> str:
    vals = result.preset.paper.get(controller, {})
    return "; ".join(f"{k} {v:g}" for k, v in vals.items()) if vals else ""


def format_table(result: CompareResult) -> list[str]:
    """Printable lines: one per run specification and operating point (means over the initial rotor
    angles, `runs` of them), the paper's figures (where its text gives them) in the last column."""
    rows = [_HEAD]
    for r in aggregate(result.rows):
        name = r["label"] + (" (equal f_av)" if r["group"] == "equal_fav" else "")
        narrow = (f"{r['narrow_pulses']:.0f}/{r['narrow_pulses_gated']:.0f}"
                  if r.get("narrow_pulses") is not None and r.get("narrow_pulses_gated") is not None else "-")
        rows.append((name, _fmt(r["ts_us"], ".1f"), _fmt(r["speed_rpm"], ".0f"), _fmt(r["load_nm"], ".2f"),
                     _fmt(r["torque_ripple_rms_nm"], ".3f"), _fmt(r["torque_ripple_pp_nm"], ".3f"),
                     _fmt(r["current_thd_pct"], ".2f"), _fmt(r["current_thd_total_pct"], ".2f"),
                     _fmt(r["switching_freq_khz"], ".2f"), _fmt(r["switching_freq_intra_khz"], ".2f"), narrow,
                     _fmt(r["eval_e"], ".3f"), _fmt(r["candidates_evaluated_mean"], ".0f"),
                     _fmt(r["torque_error_mean_nm"], "+.3f"), _fmt(r["candidate_miss_rate"], ".3f"),
                     _fmt(r["t_reach_98pct_s"], ".3f"), str(r["n_runs"]), _fmt(r["xy_current_rms_a"], ".1f"),
                     _fmt(r["current_distortion_rms_a"], ".1f"), str(r["n_trips"]),
                     _paper(result, r["label"]) if r["group"] == "main" else ""))
    lines = _column_blocks([row[:-1] for row in rows], TABLE_WIDTH)
    for row in rows[1:]:  # the paper's figures below the table: they do not fit a column
        if row[-1]:
            lines += textwrap.wrap(f"paper, {row[0]}: {row[-1]}", TABLE_WIDTH, subsequent_indent="  ")
    if result.preset.paper_note:
        lines += textwrap.wrap(f"paper: {result.preset.paper_note}", TABLE_WIDTH, subsequent_indent="  ")
    return lines


def _column_blocks(rows: list[tuple[str, ...]], width: int) -> list[str]:
    """The table as blocks of whole columns, each at most `width` characters wide (the first column, the run
    name, repeated in every block; blocks separated by a blank line)."""
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    lines: list[str] = []
    col = 1
    while col < len(widths):
        cols, used = [0], widths[0]
        while col < len(widths) and (len(cols) == 1 or used + 2 + widths[col] <= width):
            cols.append(col)
            used += 2 + widths[col]
            col += 1
        block = ["  ".join(row[c].ljust(widths[c]) for c in cols).rstrip() for row in rows]
        block.insert(1, "-" * max(len(line) for line in block))
        lines += ([""] if lines else []) + block
    return lines


def write_json(result: CompareResult, path: Path) -> None:
    """Rows, the paper's figures and (accel) the series as JSON."""
    p = result.preset
    payload = {"preset": p.name, "description": p.description, "motor": p.motor, "scenario": p.scenario,
               "paper": p.paper, "paper_note": p.paper_note, "rows": result.rows,
               "aggregates": aggregate(result.rows), "series": result.series}
    try:
        path.write_text(json.dumps(payload, indent=2) + "\n", encoding="utf-8")
    except OSError as exc:
        raise InputFileError(f"json file {path}: {exc.strerror}") from None


def write_csv(result: CompareResult, path: Path) -> None:
    """One CSV line per run (COLUMNS)."""
    try:
        with path.open("w", newline="", encoding="utf-8") as fh:
            w = csv.writer(fh)
            w.writerow(COLUMNS)
            for r in result.rows:
                w.writerow(["" if r.get(c) is None else r.get(c) for c in COLUMNS])
    except OSError as exc:
        raise InputFileError(f"csv file {path}: {exc.strerror}") from None
