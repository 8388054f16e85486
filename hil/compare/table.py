"""Comparison table: text (with the paper's figures beside ours), JSON and CSV."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

from pmsm_hil.hil.compare.runs import CompareResult
from pmsm_hil.hil.compare.spread import aggregate
from pmsm_hil.hil.errors import InputFileError
from pmsm_hil.hil.metrics.registry import row_keys

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
    widths = [max(len(row[i]) for row in rows) for i in range(len(_HEAD))]
    lines = ["  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)).rstrip() for row in rows]
    lines.insert(1, "-" * len(lines[0]))
    if result.preset.paper_note:
        lines.append(f"paper: {result.preset.paper_note}")
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
