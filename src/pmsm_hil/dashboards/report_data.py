"""Runs for the HTML report: metrics.json + run.mcap of each `hil run` output directory."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from pmsm_hil.dashboards.errors import DashboardError
from pmsm_hil.dashboards.report_end import RunEnd, run_end
from pmsm_hil.dashboards.report_whole_run import WholeRun, whole_run
from pmsm_hil.hil.runlog.errors import RunLogError
from pmsm_hil.hil.runlog.reader import read_metadata, read_periods, read_trace


@dataclass(frozen=True)
class RunData:
    """One run: label, metrics (the `--json` content), metadata, metrics-window waveforms, the whole run
    (decimated per-period series) and how it ended.

    `t` [s], `torque`/`torque_ref` [N·m], `currents` (3, n) [A] come from the 2 µs trace when the run logged
    it (`--log-trace`), else from the per-period records (one sample per Ts); `source` says which. They are
    empty when the run ended before its metrics window."""

    label: str
    path: Path
    metrics: dict[str, Any]
    metadata: dict[str, str]
    t: np.ndarray
    torque: np.ndarray
    torque_ref: np.ndarray
    currents: np.ndarray
    source: str
    whole: WholeRun
    end: RunEnd

    @property
    def has_window(self) -> bool:
        """True when the run reached its metrics window (window waveforms to draw)."""
        return len(self.t) > 0

    @property
    def fundamental_hz(self) -> float:
        """Electrical fundamental [Hz] (from the metrics, else from the mean speed and pole pairs)."""
        f1 = self.metrics.get("current_fundamental_hz")
        if isinstance(f1, (int, float)) and f1 > 0:
            return float(f1)
        pp = float(self.metadata.get("pole_pairs", "nan"))
        rpm = float(self.metrics.get("speed_mean_rpm") or math.nan)
        return pp * rpm / 60.0


def load_run(run_dir: Path) -> RunData:
    """Read one run directory (needs metrics.json and run.mcap)."""
    metrics_path, mcap_path = run_dir / "metrics.json", run_dir / "run.mcap"
    if not metrics_path.is_file() or not mcap_path.is_file():
        raise DashboardError(f"RUN_DIR: {run_dir} needs metrics.json and run.mcap (a `hil run --out` directory)")
    try:
        loaded = json.loads(metrics_path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise DashboardError(f"RUN_DIR: {metrics_path} is not readable JSON ({exc})") from None
    if not isinstance(loaded, dict):
        raise DashboardError(f"RUN_DIR: {metrics_path} must hold a JSON object, got {type(loaded).__name__}")
    metrics: dict[str, Any] = loaded
    try:
        meta = read_metadata(mcap_path)
        periods = read_periods(mcap_path)
        trace = read_trace(mcap_path)
    except RunLogError as exc:
        raise DashboardError(f"RUN_DIR: {mcap_path}: {exc}") from None
    where = str(metrics_path)
    end = run_end(metrics, periods, _float(meta.get("ts_s")), where)
    if len(periods) == 0 and not end.early:
        raise DashboardError(f"RUN_DIR: {mcap_path} holds no periods")
    n_window = min(end.window_periods, len(periods))
    window = periods[len(periods) - n_window:]
    if n_window == 0:
        t = torque = torque_ref = np.zeros(0)
        currents = np.zeros((3, 0))
        source = "no metrics window"
    elif len(trace) and float(trace["t"][-1]) > float(window["t"][0]):
        tr = trace[trace["t"] >= float(window["t"][0])]
        t, torque = tr["t"], tr["torque"]
        currents = np.stack([tr["i_a"], tr["i_b"], tr["i_c"]])
        torque_ref = np.interp(t, window["t"], np.nan_to_num(window["torque_ref"], nan=np.nan))
        source = "trace (2 µs)"
    else:
        t, torque, torque_ref = window["t"], window["torque"], window["torque_ref"]
        currents = np.stack([window["i_a"], window["i_b"], window["i_c"]])
        source = "period samples"
    label = f"{metrics.get('controller', meta.get('controller', '?'))} · {run_dir.name}"
    return RunData(label, run_dir, metrics, meta, np.asarray(t, float), np.asarray(torque, float),
                   np.asarray(torque_ref, float), np.asarray(currents, float), source, whole_run(periods), end)


def _float(text: str | None) -> float | None:
    """A metadata number, None if absent or not a finite number."""
    try:
        value = float(text) if text is not None else math.nan
    except ValueError:
        return None
    return value if math.isfinite(value) else None
