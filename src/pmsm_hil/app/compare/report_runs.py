"""`hil compare --report`: which runs of a preset the HTML report shows, where they log, and the page.

The report shows one operating point and one initial rotor angle: the preset's first explicit point, or
the largest value of its sweep (the rated end: 7 N·m, 1500 rpm, ...), or the scenario's own point; the
first entry of `theta0_rad`. At that point every controller/variant (and the equal-f_av run) logs to
DIR/runs/<preset>/<label>, at most MAX_REPORT_RUNS of them in run order; the others are listed on the page.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from pmsm_hil.app.compare.preset import ComparePreset, Variant
from pmsm_hil.app.compare.runs import CompareResult
from pmsm_hil.hil.atomic_write import write_text_atomic

#: most runs on one page (columns of the metrics table, rows of the waveform figure)
MAX_REPORT_RUNS = 8


def report_point(p: ComparePreset) -> dict[str, float]:
    """The operating point the report shows (keys speed_rpm / load_nm, rpm and N·m; {} = the scenario's)."""
    if p.points:
        return dict(p.points[0])
    if p.sweep_key is not None and p.sweep_values:
        return {p.sweep_key: max(p.sweep_values)}
    return {}


def _point_rule(p: ComparePreset) -> str:
    """Which rule of `report_point` chose the point, in words."""
    if p.points:
        return f"the first of the preset's {len(p.points)} points"
    if p.sweep_key is not None and p.sweep_values:
        return f"the largest value of the {p.sweep_key} sweep"
    return "the preset's operating point"


def dir_name(label: str) -> str:
    """A file-system-safe directory name for a run label ('I rot11 (11)' -> 'I-rot11-11')."""
    name = re.sub(r"[^A-Za-z0-9._=-]+", "-", label).strip("-.")
    return name or "run"


def display_name(row: dict[str, Any]) -> str:
    """Table name of a row: its label, '(equal f_av)' for the equal-f_av run."""
    label = str(row.get("label") or row.get("controller"))
    return label + (" (equal f_av)" if row.get("group") == "equal_fav" else "")


@dataclass(slots=True)
class ReportSelection:
    """`RunDirFor` of `run_preset`: a directory under `root` for each run the report shows, else None."""

    preset: ComparePreset
    root: Path
    point: dict[str, float] = field(init=False)
    dirs: dict[tuple[str, str], Path] = field(default_factory=dict)
    left_out: list[str] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.point = report_point(self.preset)

    def __call__(self, spec: Variant, point: dict[str, float], theta0_rad: float, group: str) -> Path | None:
        """The run's directory if the report shows it (the same one for every equal-f_av iteration)."""
        if point != self.point or theta0_rad != self.preset.theta0_rad[0]:
            return None
        key = (spec.label, group)
        if key in self.dirs:
            return self.dirs[key]
        if len(self.dirs) >= MAX_REPORT_RUNS:
            name = display_name({"label": spec.label, "group": group})
            if name not in self.left_out:
                self.left_out.append(name)
            return None
        base = dir_name(spec.label) + ("-equal-fav" if group == "equal_fav" else "")
        used = {d.name for d in self.dirs.values()}
        name, n = base, 2
        while name in used:
            name, n = f"{base}-{n}", n + 1
        self.dirs[key] = self.root / name
        return self.dirs[key]


@dataclass(frozen=True, slots=True)
class ReportSummary:
    """What `write_compare_report` wrote: the file, the runs shown, the runs skipped (name, reason)."""

    path: Path
    shown: list[str]
    skipped: list[tuple[str, str]]


def _run_label(row: dict[str, Any]) -> str:
    """'<name> · <controller>, Ts = x µs' (the report's bar charts use the part before ' · ')."""
    ctrl = str(row["controller"])
    extra = "" if ctrl == row.get("label", ctrl) else f"{ctrl}, "
    return f"{display_name(row)} · {extra}Ts = {float(row['ts_us']):g} µs"


def _point_text(row: dict[str, Any]) -> str:
    return f"{float(row['speed_rpm']):g} rpm, {float(row['load_nm']):g} N·m"


def write_compare_report(result: CompareResult, selection: ReportSelection, out: Path) -> ReportSummary:
    """Write the HTML report of the runs `selection` logged; runs that did not complete (plant trip,
    watchdog, fault) are skipped and named in a note. DashboardError if none completed or `out` fails."""
    from pmsm_hil.dashboards.errors import DashboardError
    from pmsm_hil.dashboards.report_data import load_run
    from pmsm_hil.dashboards.report_html import render_report

    p = result.preset
    logged = [r for r in result.rows if r.get("run_dir")]
    done = [r for r in logged if r.get("end_reason") == "completed"]
    skipped = [(display_name(r), str(r.get("end_reason"))) for r in logged if r.get("end_reason") != "completed"]
    if not done:
        why = "; ".join(f"{n}: {reason}" for n, reason in skipped) or "no run at the report's operating point"
        raise DashboardError(f"--report: no run of preset '{p.name}' completed its metrics window ({why})")
    runs = [replace(load_run(Path(r["run_dir"])), label=_run_label(r)) for r in done]
    angle = p.theta0_rad[0]
    notes = [f"Preset {p.name}: {p.description}"] if p.description else []
    notes.append(f"Operating point {_point_text(done[0])} ({_point_rule(p)}), initial rotor angle {angle:g} rad "
                 f"(electrical, the first of {len(p.theta0_rad)}): one run per controller/variant, at most "
                 f"{MAX_REPORT_RUNS}; the JSON/CSV written beside this page hold every run. "
                 f"Run directories: {selection.root}.")
    if skipped:
        notes.append("Skipped (no usable metrics window): "
                     + "; ".join(f"{n}: {reason}" for n, reason in skipped) + ".")
    if selection.left_out:
        notes.append(f"Not shown (more than {MAX_REPORT_RUNS} runs; narrow the preset with --controllers): "
                     + ", ".join(selection.left_out) + ".")
    title = f"hil compare {p.name}: {p.motor}, {p.scenario} scenario"
    text = render_report(runs, title, notes=notes, generator=f"hil compare --preset {p.name} --report")
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DashboardError(f"--report {out}: {exc.strerror}") from None
    write_text_atomic(out, text, option="--report")
    return ReportSummary(out, [r.label for r in runs], skipped)
