"""How a run ended (metrics.json `end_reason`, `end_code`, `end_period`) for the HTML report: the box of a run
that ended early and the sentence that replaces its metrics-window charts."""

from __future__ import annotations

import html
from dataclasses import dataclass
from typing import Any

import numpy as np

from pmsm_hil.dashboards.errors import DashboardError
from pmsm_hil.hil.runner.contract import EndCode


def _int_field(metrics: dict[str, Any], key: str, where: str, minimum: int) -> int | None:
    value = metrics.get(key)
    if value is None:
        return None
    if not isinstance(value, int) or isinstance(value, bool) or value < minimum:
        raise DashboardError(f"RUN_DIR: {where}: '{key}' must be a whole number ≥ {minimum}, got {value!r}")
    return value


@dataclass(frozen=True, slots=True)
class RunEnd:
    """The end of a run: reason, code (`EndCode`, None if metrics.json predates it), index of the last period
    run (−1: none), its start time [s] (None when unknown) and the number of metrics-window periods."""

    reason: str
    code: int | None
    period: int | None
    t_s: float | None
    window_periods: int

    @property
    def early(self) -> bool:
        """True when the run did not complete (trip, watchdog, DUT violation, target crash, interrupt)."""
        return self.code is not None and self.code != int(EndCode.COMPLETED)

    @property
    def code_name(self) -> str:
        """'safety stop', 'DUT violation', ... for the code ('' if none or unknown)."""
        if self.code is None:
            return ""
        try:
            return EndCode(self.code).name.lower().replace("_", " ").replace("dut", "DUT")
        except ValueError:
            return "unknown code"

    def where(self) -> str:
        """'at period 309 (t = 30.900 ms)' (t ≥ 1 s: in s), 'before the first period' or 'at a period not
        recorded'."""
        if self.period is None:
            return "at a period not recorded"
        if self.period < 0:
            return "before the first period"
        at = ""
        if self.t_s is not None:
            at = f" (t = {self.t_s * 1e3:.3f} ms)" if abs(self.t_s) < 1.0 else f" (t = {self.t_s:.4f} s)"
        return f"at period {self.period}{at}"


def run_end(metrics: dict[str, Any], periods: np.ndarray, ts_s: float | None, where: str) -> RunEnd:
    """`RunEnd` of a run from its metrics and logged periods (`where`: metrics.json path, for errors).

    The end time is the logged start of period `end_period`, else end_period · Ts when the log is shorter."""
    reason = metrics.get("end_reason", "completed")
    if not isinstance(reason, str):
        raise DashboardError(f"RUN_DIR: {where}: 'end_reason' must be a string, got {reason!r}")
    code = _int_field(metrics, "end_code", where, 0)
    period = _int_field(metrics, "end_period", where, -1)
    window = _int_field(metrics, "periods", where, 0)
    t_s: float | None = None
    if period is not None and 0 <= period < len(periods):
        t_s = float(periods["t"][period])
    elif period is not None and period >= 0 and ts_s is not None:
        t_s = period * ts_s
    return RunEnd(reason, code, period, t_s, len(periods) if window is None else window)


def end_box(label: str, end: RunEnd, anchor: str) -> str:
    """HTML box saying where and why a run ended early (empty for a completed run)."""
    if not end.early:
        return ""
    code = f"{end.code} ({end.code_name})" if end.code_name else str(end.code)
    return (f"<div class=\"end\" id=\"{anchor}\"><b>{html.escape(label)} ended early</b> "
            f"{html.escape(end.where())}: {html.escape(end.reason)}<br>"
            f"<span class=\"note\">end_code {html.escape(code)}, end_period {end.period}, "
            f"metrics-window periods {end.window_periods}</span></div>")


def no_window_sentence(label: str, end: RunEnd) -> str:
    """Why a run has no metrics-window charts (it ended before its window began)."""
    if end.early:
        return f"{label} ended {end.where()}, before its metrics window began: {end.reason}."
    return f"{label} logged no metrics-window period."
