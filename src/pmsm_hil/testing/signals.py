"""Signals of a run and assertions on them: tolerance bands over time windows, step-response figures.

A `Signal` is two numpy arrays, `t` [s] (run time, increasing) and `y`, with a name and a unit. Every
assertion raises `SignalAssertionError` (an AssertionError) whose message names the signal, the bound and
the worst violation (its time and value); when a report is active (the `hil` fixture), a PNG of the signal
with its band is written first and its path is recorded in the JUnit XML (`hil_plot` property) and named in
the message.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, NoReturn, Protocol

import numpy as np
import numpy.typing as npt

from pmsm_hil.errors import HilError

if TYPE_CHECKING:
    from pmsm_hil.testing.report import PlotRequest, Reporter


class SignalAssertionError(HilError, AssertionError):
    """A signal left its band (the message names the signal, the bound and the worst violation)."""


@dataclass(frozen=True, eq=False)
class Signal:
    """Samples `y` at times `t` [s] (1-D, same length, `t` non-decreasing); `name` and `unit` for messages."""

    name: str
    t: npt.NDArray[np.float64]
    y: npt.NDArray[np.float64]
    unit: str = ""
    #: where a failing assertion writes its plot (set for the signals of a `hil` run)
    reporter: Reporter | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        t = np.asarray(self.t, dtype=np.float64)
        y = np.asarray(self.y, dtype=np.float64)
        if t.ndim != 1 or y.shape != t.shape:
            raise ValueError(f"signal {self.name}: t and y must be 1-D of the same length, got {t.shape} and {y.shape}")
        if len(t) > 1 and not np.all(np.diff(t) >= 0):
            raise ValueError(f"signal {self.name}: t must be non-decreasing")
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "y", y)

    def __len__(self) -> int:
        return len(self.t)

    def between(self, t0: float | None = None, t1: float | None = None) -> Signal:
        """The samples with t0 ≤ t ≤ t1 (None: open end)."""
        mask = _mask(self.t, t0, t1)
        return Signal(self.name, self.t[mask], self.y[mask], self.unit, self.reporter)

    def at(self, t: float) -> float:
        """Value at time `t` [s], linearly interpolated (clamped to the first/last sample)."""
        if not len(self):
            raise ValueError(f"signal {self.name} has no samples")
        return float(np.interp(t, self.t, self.y))

    def mean(self, t0: float | None = None, t1: float | None = None) -> float:
        """Mean over [t0, t1] (NaN without samples)."""
        y = self.y[_mask(self.t, t0, t1)]
        return float(y.mean()) if len(y) else math.nan


def _mask(t: npt.NDArray[np.float64], t0: float | None, t1: float | None) -> npt.NDArray[np.bool_]:
    mask = np.ones(len(t), dtype=bool)
    if t0 is not None:
        mask &= t >= t0
    if t1 is not None:
        mask &= t <= t1
    return mask


def _fmt(x: float, unit: str = "") -> str:
    text = f"{x:.6g}"
    return f"{text} {unit}" if unit else text


def _span(t0: float, t1: float) -> str:
    return f"[{t0:.6g}, {t1:.6g}] s"


def _fail(sig: Signal, assertion: str, message: str, plot: PlotRequest | None) -> NoReturn:
    """Write the plot (when a report is active), then raise with the message (+ the plot path)."""
    __tracebackhide__ = True
    from pmsm_hil.testing.report import active_reporter

    reporter = sig.reporter or active_reporter()
    if reporter is not None and plot is not None:
        path = reporter.plot(assertion, sig, plot)
        message += f"; plot: {path}"
    raise SignalAssertionError(f"{assertion}: {message}")


def _check_band(sig: Signal, assertion: str, lo: float, hi: float, t0: float | None, t1: float | None,
                bound: str, where: str) -> None:
    """Every sample of `sig` in [t0, t1] inside [lo, hi]; NaN counts as outside."""
    __tracebackhide__ = True
    from pmsm_hil.testing.report import PlotRequest

    mask = _mask(sig.t, t0, t1)
    window = (sig.t[0] if t0 is None and len(sig) else t0, sig.t[-1] if t1 is None and len(sig) else t1)
    plot = PlotRequest(lo=lo, hi=hi, t0=window[0], t1=window[1])
    if not mask.any():
        last = f"{sig.t[-1]:.6g} s" if len(sig) else "no samples at all"
        _fail(sig, assertion, f"{sig.name}: no samples {where} (the signal ends at {last})", plot)
    y = sig.y[mask]
    excess = np.maximum(lo - y, y - hi)
    excess = np.where(np.isnan(y), np.inf, excess)
    worst = int(np.argmax(excess))
    if excess[worst] > 0.0:
        t_worst = float(sig.t[mask][worst])
        n_out = int(np.count_nonzero(excess > 0.0))
        plot = PlotRequest(lo=lo, hi=hi, t0=window[0], t1=window[1], worst=(t_worst, float(y[worst])))
        _fail(sig, assertion, f"{sig.name} not {bound} {where}: worst {_fmt(float(y[worst]), sig.unit)} at "
                              f"t = {t_worst:.6g} s ({n_out} of {len(y)} samples outside)", plot)


def assert_settles(sig: Signal, to: float, tol: float, within: float, t0: float | None = None) -> None:
    """`sig` stays inside [to − tol, to + tol] from t0 + within [s] to its end (t0: default the first sample)."""
    __tracebackhide__ = True
    _check_tol(tol)
    start = (float(sig.t[0]) if len(sig) else 0.0) if t0 is None else t0
    deadline = start + within
    lo, hi = to - tol, to + tol
    if len(sig) and deadline > sig.t[-1]:
        from pmsm_hil.testing.report import PlotRequest

        _fail(sig, "assert_settles", f"{sig.name} ends at t = {sig.t[-1]:.6g} s, before the settling deadline "
                                     f"t0 + within = {deadline:.6g} s", PlotRequest(lo=lo, hi=hi, t0=deadline))
    _check_band(sig, "assert_settles", lo, hi, deadline, None,
                f"within {_fmt(to, sig.unit)} ± {_fmt(tol)} ([{lo:.6g}, {hi:.6g}])",
                f"from t = {deadline:.6g} s (t0 {start:.6g} s + {within:.6g} s) to the end")


def assert_is_constant(sig: Signal, around: float, tol: float,
                       during: tuple[float, float] | None = None) -> None:
    """`sig` inside [around − tol, around + tol] during (t0, t1) [s] (default: the whole signal)."""
    __tracebackhide__ = True
    _check_tol(tol)
    t0, t1 = during if during is not None else (None, None)
    lo, hi = around - tol, around + tol
    where = f"during {_span(t0, t1)}" if t0 is not None and t1 is not None else "over the whole signal"
    _check_band(sig, "assert_is_constant", lo, hi, t0, t1,
                f"constant at {_fmt(around, sig.unit)} ± {_fmt(tol)} ([{lo:.6g}, {hi:.6g}])", where)


def assert_below(sig: Signal, limit: float, during: tuple[float, float] | None = None) -> None:
    """Every sample of `sig` ≤ limit during (t0, t1) [s] (default: the whole signal)."""
    __tracebackhide__ = True
    t0, t1 = during if during is not None else (None, None)
    where = f"during {_span(t0, t1)}" if t0 is not None and t1 is not None else "over the whole signal"
    _check_band(sig, "assert_below", -math.inf, limit, t0, t1, f"below {_fmt(limit, sig.unit)}", where)


def _check_tol(tol: float) -> None:
    if not (math.isfinite(tol) and tol >= 0.0):
        raise ValueError(f"tol must be a finite value ≥ 0, got {tol}")


@dataclass(frozen=True, slots=True)
class StepInfo:
    """Step-response figures of a signal after a step at `t_step` [s] (NaN when not defined, e.g. a response
    that never reaches 90 % has no rise time, one that ends outside the 2 % band no settling time)."""

    #: 10 % → 90 % of the change from `initial` to `final` [s]
    rise_time_s: float
    #: from the step until the signal stays within 2 % of the change around `final` [s]
    settling_time_s: float
    #: largest excursion beyond `final`, in % of the change (0 when none)
    overshoot_pct: float
    #: reference − final (NaN without a reference)
    steady_state_error: float
    initial: float
    final: float
    peak: float
    peak_time_s: float


def stepinfo(sig: Signal, t_step: float, *, ref: float | None = None, final: float | None = None) -> StepInfo:
    """Step-response figures of `sig` after a step at `t_step` [s].

    initial: the value at t_step (interpolated); final: `final`, else the mean of the last 5 % of the samples
    after the step; steady_state_error: `ref` − final (NaN without `ref`)."""
    after = sig.between(t_step, None)
    if len(after) < 2:
        raise ValueError(f"stepinfo: {sig.name} has fewer than 2 samples after t_step = {t_step} s")
    t, y = after.t, after.y
    y0 = sig.at(t_step)
    yf = float(y[-max(1, len(y) // 20):].mean()) if final is None else float(final)
    delta = yf - y0
    nan = math.nan
    if delta == 0.0 or not math.isfinite(delta):
        return StepInfo(nan, nan, nan, nan if ref is None else ref - yf, y0, yf, nan, nan)
    x = (y - y0) / delta  # normalised: 0 at the start, 1 at the final value
    rise = _first_crossing(t, x, 0.9) - _first_crossing(t, x, 0.1)
    outside = np.flatnonzero(np.abs(x - 1.0) > 0.02)
    if not len(outside):
        settle = 0.0
    elif outside[-1] == len(x) - 1:
        settle = nan
    else:
        i = int(outside[-1])
        edge = 1.0 + 0.02 * np.sign(x[i] - 1.0)
        settle = _interp_crossing(t[i], t[i + 1], x[i], x[i + 1], edge) - t_step
    ipeak = int(np.argmax(x))
    overshoot = max(0.0, 100.0 * (float(x[ipeak]) - 1.0))
    return StepInfo(rise_time_s=rise, settling_time_s=settle, overshoot_pct=overshoot,
                    steady_state_error=nan if ref is None else ref - yf, initial=y0, final=yf,
                    peak=float(y[ipeak]), peak_time_s=float(t[ipeak]))


def _first_crossing(t: npt.NDArray[np.float64], x: npt.NDArray[np.float64], level: float) -> float:
    """First time the normalised response x reaches `level` (linear interpolation), NaN if never."""
    idx = np.flatnonzero(x >= level)
    if not len(idx):
        return math.nan
    i = int(idx[0])
    if i == 0:
        return float(t[0])
    return _interp_crossing(t[i - 1], t[i], x[i - 1], x[i], level)


def _interp_crossing(ta: float, tb: float, xa: float, xb: float, level: float) -> float:
    return float(ta + (tb - ta) * (level - xa) / (xb - xa)) if xb != xa else float(tb)


# --- metrics of a run ----------------------------------------------------------------------------------
#: metric keys (src/pmsm_hil/hil/metrics/registry.py) of the two metric assertions
TORQUE_RIPPLE_KEY = "torque_ripple_rms_nm"
CURRENT_THD_KEY = "current_thd_pct"


class _HasMetrics(Protocol):
    """What the metric assertions need of a run result (`pmsm_hil.testing.HilResult`)."""

    @property
    def metrics(self) -> Mapping[str, Any]: ...

    @property
    def window(self) -> tuple[float, float]: ...

    def signal(self, name: str) -> Signal: ...


def assert_ripple_below(result: _HasMetrics, nm: float) -> None:
    """The run's torque ripple RMS (`torque_ripple_rms_nm`, metrics window) ≤ nm [N·m]."""
    __tracebackhide__ = True
    _metric_below(result, TORQUE_RIPPLE_KEY, nm, "torque_nm", "assert_ripple_below", "torque ripple RMS", "N·m")


def assert_thd_below(result: _HasMetrics, pct: float) -> None:
    """The run's phase-current THD (`current_thd_pct`, harmonics 2..40 of i_a, metrics window) ≤ pct [%]."""
    __tracebackhide__ = True
    _metric_below(result, CURRENT_THD_KEY, pct, "i_a", "assert_thd_below", "current THD", "%")


def _metric_below(result: _HasMetrics, key: str, limit: float, signal: str, assertion: str, what: str,
                  unit: str) -> None:
    __tracebackhide__ = True
    from pmsm_hil.testing.report import PlotRequest

    value = result.metrics.get(key)
    t0, t1 = result.window
    sig = result.signal(signal).between(t0, t1)
    if value is None:
        note = result.metrics.get("current_thd_note") or result.metrics.get("end_reason", "")
        _fail(sig, assertion, f"{what} of {signal} ({key}) is null: {note}", PlotRequest(t0=t0, t1=t1))
    if float(value) <= limit:
        return
    mean = sig.mean()
    dev = sig.y - mean
    worst = int(np.argmax(np.abs(dev))) if len(sig) else -1
    where = (f"; largest deviation from the mean {_fmt(mean, sig.unit)}: {float(dev[worst]):+.6g} {sig.unit} at "
             f"t = {sig.t[worst]:.6g} s") if worst >= 0 else ""
    band = limit if key == TORQUE_RIPPLE_KEY else math.nan
    plot = PlotRequest(lo=mean - band, hi=mean + band, t0=t0, t1=t1,
                       worst=(float(sig.t[worst]), float(sig.y[worst])) if worst >= 0 else None,
                       title=f"{what} {float(value):.4g} {unit} > {limit:g} {unit}")
    _fail(sig, assertion, f"{what} of {signal} ({key}) = {_fmt(float(value), unit)} above the bound "
                          f"{_fmt(limit, unit)} over the metrics window {_span(t0, t1)}{where}", plot)


__all__ = ["CURRENT_THD_KEY", "TORQUE_RIPPLE_KEY", "Signal", "SignalAssertionError", "StepInfo", "assert_below",
           "assert_is_constant", "assert_ripple_below", "assert_settles", "assert_thd_below", "stepinfo"]
