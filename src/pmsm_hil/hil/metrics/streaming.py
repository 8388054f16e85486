"""`WindowMetrics`: the run's window metrics accumulated block by block while the run goes on.

Memory does not grow with the window: sums, counts and time-weighted moments are exact running figures
(see `moments.py`), execution-time quantiles come from counts of the integer ns values (`quantiles.py`,
identical to numpy's), and current THD is computed at the end over the last `THD_SPAN_S` seconds of the
window trace (`trace_tail.py`; the whole window when it is shorter, which all bundled scenarios and
comparison presets are), with the fundamental from the mean speed over that span.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from pmsm_hil.hil.metrics._validate import require_fields, require_int, require_positive
from pmsm_hil.hil.metrics.errors import MetricsError, MetricsWindowError
from pmsm_hil.hil.metrics.moments import TrapezoidWeights, WeightedMoments, buffer_room
from pmsm_hil.hil.metrics.quantiles import IntQuantiles
from pmsm_hil.hil.metrics.stator_frequency import MAX_CHANGE_PCT, stator_frequency
from pmsm_hil.hil.metrics.switching import SwitchingStats, switching_from_counts
from pmsm_hil.hil.metrics.thd import current_thd, fundamental_hz
from pmsm_hil.hil.metrics.timing import SPLIT_NAMES
from pmsm_hil.hil.metrics.trace_tail import TraceTail
from pmsm_hil.hil.records import PERIOD_DTYPE, TRACE_DTYPE

#: THD span [s]: the last this-many seconds of the window trace (whole electrical periods of it)
THD_SPAN_S = 1.0
LINK_KEYS = ("frames_tx", "frames_rx", "crc_errors", "lost", "late")
#: what `torque_error_mean_nm` is measured against (`torque_error_reference`)
HOLD_TORQUE = "hold: load + B·ω_ref + J·dω_ref/dt"
#: Below this electrical frequency (Hz) the speed is taken as zero and THD is reported as null.
SPEED_ZERO_HZ = 0.1
RAD_S_TO_RPM = 60.0 / (2.0 * math.pi)
_PERIOD_FIELDS = tuple(PERIOD_DTYPE.names or ())
_TRACE_FIELDS = tuple(TRACE_DTYPE.names or ())


def _link(link_stats: Mapping[str, int]) -> dict[str, int]:
    if not isinstance(link_stats, Mapping):
        raise MetricsError(f"link_stats: expected a mapping, got {type(link_stats).__name__}")
    return {key: require_int(link_stats.get(key, 0), f"link_stats[{key!r}]", 0) for key in LINK_KEYS}


class WindowMetrics:
    """Accumulates PERIOD_DTYPE blocks (`add_periods`) and trace blocks (`add_trace`) of the metrics window;
    `result(...)` gives the metrics dictionary (the CLI contract, see `compute_run_metrics`)."""

    def __init__(self, trace_dtype: np.dtype = TRACE_DTYPE, *, thd_span_s: float = THD_SPAN_S) -> None:
        self.torque = WeightedMoments()
        self.speed = WeightedMoments()
        names = trace_dtype.names or ()
        self.xy_sq: WeightedMoments | None = WeightedMoments() if "i_x" in names else None
        self.tail = TraceTail(trace_dtype, thd_span_s)
        self.weights = TrapezoidWeights()  # of the trace times, shared by the moments
        self._cols = [np.empty(0) for _ in range(3)]  # contiguous columns of the current block
        self._dt = np.empty(0)
        self.exec_us = IntQuantiles(1e-3)
        self.split_us = [IntQuantiles(1e-3) for _ in SPLIT_NAMES]
        self.periods = 0
        self.transitions = self.boundary = self.narrow = self.narrow_gated = 0
        self.candidates = self.late = self.missed = 0
        self.load_sum = 0.0
        #: the host's speed reference [rad/s] over the window: sum, count, first and last finite value
        self.speed_ref_sum, self.speed_ref_n = 0.0, 0
        self.speed_ref_first: float | None = None
        self.speed_ref_last: float | None = None
        self._last_t = -math.inf

    def add_periods(self, block: np.ndarray, *, cold: int = 0) -> None:
        """Add a block of period records (PERIOD_DTYPE fields, in order); the execution times of its first `cold`
        records (the run's cold start, reported apart: `exec_time_first_us`) are left out of `exec_time_us`."""
        require_fields(block, _PERIOD_FIELDS, "periods")
        n = block.shape[0]
        if n == 0:
            return
        self.periods += n
        self.transitions += int(np.sum(block["leg_transitions"], dtype=np.int64))
        self.boundary += int(np.sum(block["boundary_transitions"], dtype=np.int64))
        self.narrow += int(np.sum(block["narrow_pulses"], dtype=np.int64))
        self.narrow_gated += int(np.sum(block["narrow_pulses_gated"], dtype=np.int64))
        self.exec_us.add(block["exec_time_ns"][cold:])
        warm = np.asarray(block["exec_split_ns"][cold:])
        if warm.shape[0]:  # a block all cold start (a run ended within its first periods) has no split to add
            split = warm.reshape(warm.shape[0], -1)
            for k, acc in enumerate(self.split_us[: split.shape[1]]):
                acc.add(split[:, k])
        self.candidates += int(np.sum(block["candidates"], dtype=np.int64))
        self.late += int(np.count_nonzero(block["late"]))
        self.missed += int(np.count_nonzero(block["missed"]))
        ref = np.asarray(block["speed_ref"], dtype=np.float64)
        finite = np.isfinite(ref)
        if finite.any():
            kept = ref[finite]
            self.speed_ref_sum += float(np.sum(kept))
            self.speed_ref_n += int(kept.shape[0])
            if self.speed_ref_first is None:
                self.speed_ref_first = float(kept[0])
            self.speed_ref_last = float(kept[-1])
        self.load_sum += float(np.sum(block["load_torque"], dtype=np.float64))

    def add_trace(self, block: np.ndarray) -> None:
        """Add a block of trace records (times strictly increasing, after the previous block's)."""
        require_fields(block, _TRACE_FIELDS, "trace")
        n = block.shape[0]
        if n == 0:
            return
        t = self._column(0, block["t"])
        self._dt = buffer_room(self._dt, n)
        dt = np.subtract(t[1:], t[:-1], out=self._dt[: n - 1])
        t0, t1 = float(t[0]), float(t[-1])
        if not (math.isfinite(t0) and math.isfinite(t1) and t0 > self._last_t and bool(np.all(dt > 0.0))):
            if not np.all(np.isfinite(t)):  # finite ends and positive steps: all finite
                raise MetricsError("trace.t: contains non-finite times")
            raise MetricsError("trace.t: times must be strictly increasing")
        self._last_t = t1
        self.weights.add(t, dt)
        self.torque.add_weighted(self._column(1, block["torque"]), self.weights)
        self.speed.add_weighted(self._column(1, block["omega_m"]), self.weights)
        if self.xy_sq is not None:
            ix, iy = self._column(1, block["i_x"]), self._column(2, block["i_y"])
            np.multiply(ix, ix, out=ix)
            self.xy_sq.add_weighted(np.add(ix, np.multiply(iy, iy, out=iy), out=ix), self.weights)
        self.tail.add(block)

    def _column(self, k: int, values: np.ndarray) -> np.ndarray:
        """`values` (a field of a block) as contiguous float64 in the reused buffer k."""
        n = values.shape[0]
        self._cols[k] = buffer_room(self._cols[k], n)
        out = self._cols[k][:n]
        np.copyto(out, values, casting="unsafe")
        return out

    def hold_torque(self, ts_s: float, friction_nms: float, inertia_kgm2: float) -> float:
        """Mean torque [N·m] the drive must deliver over the window to follow the host's speed reference:
        T_load + B·ω_ref + J·dω_ref/dt (means; the last term J·(ω_ref,last − ω_ref,first)/(N·Ts)). Only what the
        host knows, for every target; without a speed reference in the records, the mean load."""
        load = self.load_sum / self.periods
        if not self.speed_ref_n or self.speed_ref_first is None or self.speed_ref_last is None:
            return load
        accel = (self.speed_ref_last - self.speed_ref_first) / (self.periods * ts_s)
        return load + friction_nms * self.speed_ref_sum / self.speed_ref_n + inertia_kgm2 * accel

    def switching(self, ts_s: float, legs: int) -> SwitchingStats:
        """Switching statistics of the periods added so far."""
        return switching_from_counts(self.periods, self.transitions, self.boundary, self.narrow,
                                     self.narrow_gated, ts_s=ts_s, legs=legs)

    def result(self, *, ts_s: float, pole_pairs: int, legs: int = 3, wall_time_s: float,
               link_stats: Mapping[str, int], deadline_misses: int, friction_nms: float = 0.0,
               inertia_kgm2: float = 0.0) -> dict[str, Any]:
        """The metrics dictionary; `MetricsWindowError` if no period or trace record was added. `friction_nms`
        (B [N·m·s/rad]) and `inertia_kgm2` (J [kg·m²]) of the mechanics give the torque the drive must deliver
        to follow the speed reference (`torque_error_mean_nm`, `hold_torque`)."""
        if self.periods == 0:
            raise MetricsWindowError("periods: metrics window holds 0 record(s), at least 1 needed")
        if self.torque.samples == 0:
            raise MetricsWindowError("trace: metrics window holds 0 record(s), at least 1 needed")
        ts = require_positive(ts_s, "ts_s")
        p = require_int(pole_pairs, "pole_pairs", 1)
        misses = require_int(deadline_misses, "deadline_misses", 0)
        try:
            wall = float(wall_time_s)
        except (TypeError, ValueError):
            raise MetricsError(f"wall_time_s: expected a number, got {wall_time_s!r}") from None
        if not math.isfinite(wall) or wall < 0.0:
            raise MetricsError(f"wall_time_s: expected a finite value ≥ 0, got {wall_time_s!r}")
        n = self.periods
        ref_mean = self.hold_torque(ts, friction_nms, inertia_kgm2)
        mean_torque = self.torque.mean
        switching = self.switching(ts, legs)
        metrics: dict[str, Any] = {
            "periods": n,
            "sim_time_s": n * ts,
            "wall_time_s": wall,
            "loop_rate_hz": n / wall if wall > 0.0 else None,
            "torque_mean_nm": mean_torque,
            "torque_ripple_rms_nm": self.torque.rms_deviation,
            "torque_ripple_pp_nm": self.torque.maximum - self.torque.minimum,
            "torque_error_mean_nm": mean_torque - ref_mean,
            "torque_error_reference": HOLD_TORQUE,
            "load_torque_mean_nm": self.load_sum / n,
            "speed_mean_rpm": self.speed.mean * RAD_S_TO_RPM,
        }
        metrics.update(self._thd(p))
        metrics["current_distortion_rms_a"] = _distortion_rms(metrics)
        if self.xy_sq is not None:
            metrics["xy_current_rms_a"] = math.sqrt(self.xy_sq.mean)
        metrics.update(
            {
                "switching_freq_khz": switching.freq_khz,
                "switching_freq_intra_khz": switching.freq_intra_khz,
                "exec_time_us": {"median": _finite(self.exec_us.median()),
                                 "p99": _finite(self.exec_us.percentile(99.0)), "max": _finite(self.exec_us.maximum())},
                "exec_split_us": {name: acc.median() for name, acc in zip(SPLIT_NAMES, self.split_us, strict=True)
                                  if acc.n},
                "candidates_evaluated_mean": self.candidates / n,
                "narrow_pulses": switching.narrow_pulses,
                "narrow_pulses_gated": switching.narrow_pulses_gated,
                "deadline_misses": misses,
                "late_periods": self.late,
                "missed_periods": self.missed,
                "link": _link(link_stats),
            }
        )
        return metrics

    def _thd(self, pole_pairs: int) -> dict[str, Any]:
        """THD block over the trace tail: phase a is the headline, b and c are listed. The fundamental is the
        stator frequency measured from the currents (`stator_frequency.py`); null with the reason in
        `current_thd_note` and `not_applicable` when undefined (speed ~ 0, a fundamental that changes)."""
        tail = self.tail.array()
        span_speed = WeightedMoments()
        span_speed.add(np.asarray(tail["t"], dtype=np.float64), tail["omega_m"])
        mean_omega = span_speed.mean
        f_rotor = fundamental_hz(mean_omega, pole_pairs)
        out: dict[str, Any] = {"current_thd_pct": None, "current_thd_total_pct": None,
                               "current_fundamental_a": None, "current_fundamental_hz": None,
                               "current_thd_phases_pct": None, "current_thd_note": None,
                               "current_rotor_electrical_hz": f_rotor, "current_fundamental_change_pct": None,
                               "not_applicable": {}}
        measured = stator_frequency(tail["t"], tail["i_a"], tail["i_b"], tail["i_c"])
        f1 = measured.hz if measured is not None else 0.0
        if measured is None or f1 < SPEED_ZERO_HZ:
            why = "currents ~ 0 or span too short" if measured is None else f"{f1:.3g} Hz"
            return _not_applicable(out, f"stator frequency ~ 0 ({why}; mean speed {mean_omega * RAD_S_TO_RPM:.3g} "
                                        "rpm): no fundamental")
        out["current_fundamental_hz"] = f1
        out["current_fundamental_change_pct"] = measured.change_pct
        if not measured.stationary:
            out["current_fundamental_hz"] = None
            return _not_applicable(out, (
                f"the stator frequency changes by {measured.change_pct:.3g} % over the THD span ("
                f"{min(measured.segments_hz):.4g}–{max(measured.segments_hz):.4g} Hz, more than "
                f"{MAX_CHANGE_PCT:g} %: a speed step or an acceleration): no single fundamental"))
        try:
            results = [current_thd(tail["t"], tail[ph], f1, field=f"trace.{ph}") for ph in ("i_a", "i_b", "i_c")]
        except MetricsWindowError as exc:
            return _not_applicable(out, str(exc))
        out.update(
            current_thd_pct=results[0].thd_pct,
            current_thd_total_pct=results[0].thd_total_pct,
            current_fundamental_a=results[0].fundamental_a,
            current_thd_phases_pct={ph: {"harmonics": r.thd_pct, "total": r.thd_total_pct}
                                    for ph, r in zip(("a", "b", "c"), results, strict=True)},
        )
        return out


#: the harmonic keys that are null together when the fundamental is not defined over the span
HARMONIC_KEYS = ("current_thd_pct", "current_thd_total_pct", "current_fundamental_a", "current_fundamental_hz",
                 "current_thd_phases_pct", "current_distortion_rms_a")


def _not_applicable(out: dict[str, Any], reason: str) -> dict[str, Any]:
    """`out` with the harmonic keys null and `reason` in `current_thd_note` and `not_applicable`."""
    out["current_thd_note"] = reason
    out["not_applicable"] = {key: reason for key in HARMONIC_KEYS if out.get(key) is None}
    return out


def _finite(value: float) -> float | None:
    """`value`, None when NaN (no samples)."""
    return value if math.isfinite(value) else None


def _distortion_rms(metrics: Mapping[str, Any]) -> float | None:
    """Absolute distortion of phase a [A RMS]: all non-fundamental content, fundamental_rms · THD_total.

    Beside THD because a large x-y (six-phase) or low-load current makes the fundamental a poor yardstick."""
    fund, thd_total = metrics.get("current_fundamental_a"), metrics.get("current_thd_total_pct")
    if fund is None or thd_total is None:
        return None
    return float(fund) / math.sqrt(2.0) * float(thd_total) / 100.0
