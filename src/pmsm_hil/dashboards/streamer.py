"""`PeriodStreamer`: PERIOD_DTYPE blocks → Rerun columns (`send_columns`, one call per entity per block).

Per-sample `rr.log` manages only a few thousand samples per second; one `send_columns` per entity and
block of ~1000 periods keeps up with the loop many times over. Rolling figures (torque ripple, switching
frequency) carry their window across blocks, so the result does not depend on the block size.
"""

from __future__ import annotations

import math
from typing import Final

import numpy as np
import numpy.typing as npt
import rerun as rr

from pmsm_hil.dashboards import entities as ent
from pmsm_hil.dashboards.errors import DashboardError
from pmsm_hil.dashboards.geometry import (
    CANDIDATE_CODES_3PH,
    duty_voltage_ab,
    hexagon,
    linear_limit_circle,
    mean_voltage_ab,
    six_phase_vsd,
    state_voltage_ab,
)
from pmsm_hil.hil.records import PERIOD_DTYPE

RAD_S_TO_RPM: Final = 60.0 / (2.0 * math.pi)
RIPPLE_WINDOW: Final = 200  # periods in the rolling torque-ripple window
FSW_WINDOW: Final = 1000  # periods in the rolling switching-frequency window
HIST_BINS: Final = 50

_GREY: Final = (150, 150, 150, 160)
_RED: Final = (230, 40, 40, 255)
_COLORS: Final = {ent.TORQUE: (31, 119, 180), ent.TORQUE_REF: (255, 127, 14), ent.TORQUE_LOAD: (120, 120, 120),
                  ent.RIPPLE: (148, 103, 189), ent.CURRENTS[0]: (214, 39, 40), ent.CURRENTS[1]: (44, 160, 44),
                  ent.CURRENTS[2]: (31, 119, 180), ent.SPEED: (31, 119, 180), ent.SPEED_REF: (255, 127, 14),
                  ent.EXEC_TIME: (140, 86, 75), ent.FSW: (23, 190, 207)}
_NAMES: Final = {ent.TORQUE: "torque", ent.TORQUE_REF: "torque reference", ent.TORQUE_LOAD: "load torque",
                 ent.RIPPLE: f"ripple RMS ({RIPPLE_WINDOW} periods)", ent.CURRENTS[0]: "i_a", ent.CURRENTS[1]: "i_b",
                 ent.CURRENTS[2]: "i_c", ent.SPEED: "speed", ent.SPEED_REF: "speed reference",
                 ent.EXEC_TIME: "controller execution time", ent.FSW: f"f_av ({FSW_WINDOW} periods)"}


class _RollingMean:
    """Mean over the last `window` samples, continued across blocks (shorter at the very start)."""

    def __init__(self, window: int) -> None:
        self.window = window
        self.tail = np.zeros(0)

    def update(self, x: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
        full = np.concatenate([self.tail, x])
        c = np.concatenate([[0.0], np.cumsum(full)])
        idx = np.arange(self.tail.shape[0], full.shape[0]) + 1  # end index (exclusive) of each new sample
        lo = np.maximum(idx - self.window, 0)
        out: npt.NDArray[np.float64] = (c[idx] - c[lo]) / (idx - lo)
        self.tail = full[-(self.window - 1):] if self.window > 1 else np.zeros(0)
        return out


class PeriodStreamer:
    """Sends period blocks of one run to a Rerun recording with the dashboard's entities.

    `vdc` [V] scales the αβ plane, `ts_s` [s] is the control period, `legs` the inverter legs."""

    def __init__(self, rec: rr.RecordingStream, *, vdc: float, ts_s: float, legs: int = 3) -> None:
        if not (vdc > 0.0 and ts_s > 0.0):
            raise DashboardError(f"vdc/ts: expected > 0, got vdc={vdc} V, ts={ts_s} s")
        if legs not in (3, 6):
            raise DashboardError(f"legs: expected 3 or 6, got {legs}")
        self.rec, self.vdc, self.ts_s, self.legs = rec, vdc, ts_s, legs
        self.periods = 0
        self._torque_mean = _RollingMean(RIPPLE_WINDOW)
        self._torque_sq = _RollingMean(RIPPLE_WINDOW)
        self._fsw = _RollingMean(FSW_WINDOW)
        self._hist: npt.NDArray[np.int64] | None = None
        self._bin_us = 0.0
        self._candidates = state_voltage_ab(np.array(CANDIDATE_CODES_3PH), vdc)
        self._static()

    def _static(self) -> None:
        log = self.rec.log
        for path, color in _COLORS.items():
            log(path, rr.SeriesLines(colors=[color], names=[_NAMES[path]], widths=[1.5]), static=True)
        v = self.vdc
        if self.legs == 6:
            ab, xy = six_phase_vsd(np.arange(64), v)
            log("/ab/vectors", rr.Points2D(ab, colors=[_GREY], radii=[0.006 * v]), static=True)
            log("/xy/vectors", rr.Points2D(xy, colors=[_GREY], radii=[0.006 * v]), static=True)
            return
        log(ent.AB_HEXAGON, rr.LineStrips2D([hexagon(v)], colors=[(90, 90, 90)], radii=[0.003 * v]), static=True)
        log(ent.AB_LIMIT, rr.LineStrips2D([linear_limit_circle(v)], colors=[(170, 170, 220)], radii=[0.0015 * v]),
            static=True)
        labels = [f"V{j}" for j in range(1, 7)]
        log("/ab/labels", rr.Points2D(1.08 * self._candidates[1:], labels=labels, radii=[0.002 * v],
                                      show_labels=True), static=True)

    def _scalar(self, path: str, times: rr.TimeColumn, values: npt.ArrayLike) -> None:
        self.rec.send_columns(path, indexes=[times], columns=rr.Scalars.columns(scalars=np.asarray(values, float)))

    def send_block(self, block: npt.NDArray[np.void]) -> None:
        """Send one PERIOD_DTYPE block (any length ≥ 0) as columns on the `time` timeline."""
        if block.dtype != PERIOD_DTYPE:
            raise DashboardError(f"block: expected PERIOD_DTYPE records, got {block.dtype}")
        n = block.shape[0]
        if n == 0:
            return
        times = rr.TimeColumn(ent.TIMELINE, duration=block["t"])
        torque = block["torque"].astype(np.float64)
        self._scalar(ent.TORQUE, times, torque)
        self._scalar(ent.TORQUE_REF, times, block["torque_ref"])
        self._scalar(ent.TORQUE_LOAD, times, block["load_torque"])
        mean = self._torque_mean.update(torque)
        sq = self._torque_sq.update(torque * torque)
        self._scalar(ent.RIPPLE, times, np.sqrt(np.maximum(sq - mean * mean, 0.0)))
        for path, field in zip(ent.CURRENTS, ("i_a", "i_b", "i_c"), strict=True):
            self._scalar(path, times, block[field])
        if self.legs == 6:
            for field, group in (("i_u", "currents"), ("i_v", "currents"), ("i_w", "currents"),
                                 ("i_x", "xy_currents"), ("i_y", "xy_currents")):
                self._scalar(f"/{group}/{field}", times, block[field])
        self._scalar(ent.SPEED, times, block["omega_m"] * RAD_S_TO_RPM)
        self._scalar(ent.SPEED_REF, times, block["speed_ref"] * RAD_S_TO_RPM)
        exec_us = block["exec_time_ns"].astype(np.float64) / 1e3
        self._scalar(ent.EXEC_TIME, times, exec_us)
        fsw = self._fsw.update(block["leg_transitions"].astype(np.float64)) / (2.0 * self.legs * self.ts_s) / 1e3
        self._scalar(ent.FSW, times, fsw)
        self._send_planes(block, times)
        self._send_histogram(exec_us, float(block["t"][-1]))
        self.periods += n

    def _send_planes(self, block: npt.NDArray[np.void], times: rr.TimeColumn) -> None:
        n = block.shape[0]
        if self.legs == 6:
            self._send_planes6(block, times)
            return
        counts = np.where(block["candidates"] > 0, self._candidates.shape[0], 0)
        vectors = np.tile(self._candidates, (n, 1))[np.repeat(counts > 0, self._candidates.shape[0])]
        cand = rr.Arrows2D.columns(vectors=vectors, colors=np.tile(np.array(_GREY, np.uint8), (vectors.shape[0], 1)),
                                   radii=np.full(vectors.shape[0], 0.004 * self.vdc, np.float32))
        self.rec.send_columns(ent.AB_CANDIDATES, indexes=[times], columns=cand.partition(counts))
        applied = mean_voltage_ab(block["states"], block["durations_ns"], block["n_states"], self.vdc)
        duty = block["n_duties"] > 0  # duty-cycle Commands: the mean voltage of the duties
        if duty.any():
            applied[duty] = duty_voltage_ab(block["duties"][duty], self.vdc)
        sel = rr.Arrows2D.columns(vectors=applied, colors=np.tile(np.array(_RED, np.uint8), (n, 1)),
                                  radii=np.full(n, 0.012 * self.vdc, np.float32))
        self.rec.send_columns(ent.AB_SELECTED, indexes=[times], columns=sel)

    def _send_planes6(self, block: npt.NDArray[np.void], times: rr.TimeColumn) -> None:
        n = block.shape[0]
        dur = block["durations_ns"].astype(np.float64)
        dur[np.arange(3)[None, :] >= block["n_states"][:, None]] = 0.0
        total = np.maximum(dur.sum(axis=1), 1.0)[:, None]
        ab, xy = six_phase_vsd(block["states"], self.vdc)  # (n, 3, 2) each
        color = np.tile(np.array(_RED, np.uint8), (n, 1))
        radii = np.full(n, 0.012 * self.vdc, np.float32)
        for path, vec in ((ent.AB_SELECTED, ab), (ent.XY_SELECTED, xy)):
            mean = (vec * dur[..., None]).sum(axis=1) / total
            self.rec.send_columns(path, indexes=[times],
                                  columns=rr.Arrows2D.columns(vectors=mean, colors=color, radii=radii))

    def _send_histogram(self, exec_us: npt.NDArray[np.float64], t_last: float) -> None:
        if self._hist is None:
            top = max(float(np.percentile(exec_us, 99.9)) * 2.0, 0.01)
            step = 10.0 ** math.floor(math.log10(top / HIST_BINS))
            for m in (1.0, 2.0, 5.0, 10.0):
                if m * step * HIST_BINS >= top:
                    step *= m
                    break
            self._bin_us = step
            self._hist = np.zeros(HIST_BINS, dtype=np.int64)
        idx = np.minimum((exec_us / self._bin_us).astype(np.int64), HIST_BINS - 1)
        self._hist += np.bincount(idx, minlength=HIST_BINS)
        centres = (np.arange(HIST_BINS) + 0.5) * self._bin_us
        self.rec.set_time(ent.TIMELINE, duration=t_last)
        self.rec.log(ent.EXEC_HIST, rr.BarChart(self._hist, abscissa=centres, color=_COLORS[ent.EXEC_TIME]))
