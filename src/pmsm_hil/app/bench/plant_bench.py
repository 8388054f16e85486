"""Plant throughput benchmark (periods per second) and the comparison with gym-electric-motor.

Every timed loop does what the HIL loop does each period: ``Plant.advance`` (validated public
API) followed by ``Plant.sample``. Figures are medians over repeats because the machine is shared.
"""

from __future__ import annotations

import math
import statistics
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass

import numpy as np

from pmsm_hil.app.bench.gem_pmsm import GEM_SOLVERS, GemPmsm, gem_installed, gem_version
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.mechanics import DynoMechanics
from pmsm_hil.hil.motor_params import PmsmParams
from pmsm_hil.hil.plant import Plant
from pmsm_hil.hil.presets_loader import load_pmsm

TRACE_DT_S = 2e-6
GEM_TIMING_METHOD = "physical_system.simulate(action) (no env reward/reference/visualisation layers)"

Commands = Sequence[tuple[list[int], list[int]]]


@dataclass(frozen=True, slots=True)
class PlantBenchResult:
    """Benchmark figures; rates in periods (steps) per second, currents in A.

    ``gem_*`` fields are None when gym-electric-motor is not importable or was skipped.
    ``gem_max_abs_di_a`` compares i_d and i_q; ``gem_max_abs_di_abc_a`` the phase currents GEM
    reports (GEM converts them with the angle of the step start).
    """

    motor: str
    speed_rpm: float
    ts_s: float
    periods: int
    repeats: int
    periods_per_s_single: float
    periods_per_s_single_trace: float
    periods_per_s_three: float
    periods_per_s_three_trace: float
    periods_per_s_single_advance_only: float
    accuracy_periods: int
    gem_version: str | None = None
    gem_timing_method: str | None = None
    gem_solver: str | None = None
    gem_steps_per_s: float | None = None
    gem_steps_per_s_euler: float | None = None
    ratio_vs_gem: float | None = None
    ratio_vs_gem_trace: float | None = None
    ratio_vs_gem_euler: float | None = None
    ratio_vs_gem_advance_only: float | None = None
    gem_max_abs_di_a: float | None = None
    gem_max_abs_di_abc_a: float | None = None
    gem_euler_max_abs_di_a: float | None = None

    def to_dict(self) -> dict[str, float | int | str | None]:
        """Flat dict for ``--json``."""
        return asdict(self)


def single_vector_commands(n: int, ts_ns: int, rng: np.random.Generator) -> list[tuple[list[int], list[int]]]:
    """n random one-state periods."""
    return [([int(s)], [ts_ns]) for s in rng.integers(0, 8, n)]


def three_vector_commands(n: int, ts_ns: int, rng: np.random.Generator) -> list[tuple[list[int], list[int]]]:
    """n random three-state periods with random ns-aligned cut points (durations sum to Ts)."""
    out: list[tuple[list[int], list[int]]] = []
    for _ in range(n):
        c0, c1 = sorted(int(c) for c in rng.integers(0, ts_ns + 1, 2))
        out.append(([int(s) for s in rng.integers(0, 8, 3)], [c0, c1 - c0, ts_ns - c1]))
    return out


def _median_rate(run_once: Callable[[], float], n: int, repeats: int) -> float:
    rates = []
    for _ in range(repeats):
        rates.append(n / max(run_once(), 1e-12))
    return float(statistics.median(rates))


def time_plant(params: PmsmParams, speed_rpm: float, ts_s: float, commands: Commands,
               trace_dt_s: float | None, repeats: int, *, with_sample: bool = True) -> float:
    """Median plant periods per second over ``repeats`` runs of ``commands``.

    Each period is ``advance`` followed by ``sample`` (what the HIL loop does and what GEM's
    ``simulate`` returns), or ``advance`` alone with ``with_sample=False``.
    """

    def run_once() -> float:
        plant = Plant(params, ts_s, DynoMechanics(speed_rpm), trace_dt_s=trace_dt_s)
        advance, sample = plant.advance, plant.sample
        if not with_sample:
            t0 = time.perf_counter()
            for states, durations in commands:
                advance(states, durations)
            return time.perf_counter() - t0
        t0 = time.perf_counter()
        for states, durations in commands:
            advance(states, durations)
            sample()
        return time.perf_counter() - t0

    return _median_rate(run_once, len(commands), repeats)


def time_gem(params: PmsmParams, speed_rpm: float, ts_s: float, codes: Sequence[int], repeats: int,
             solver: str = "default") -> float:
    """Median GEM steps per second (``simulate`` only) over ``repeats`` runs of ``codes``."""

    def run_once() -> float:
        gem = GemPmsm(params, speed_rpm, ts_s, solver)
        simulate = gem.simulate
        t0 = time.perf_counter()
        for code in codes:
            simulate(code)
        return time.perf_counter() - t0

    return _median_rate(run_once, len(codes), repeats)


def gem_deviation(params: PmsmParams, speed_rpm: float, ts_s: float, codes: Sequence[int],
                  solver: str = "default") -> tuple[float, float]:
    """Run the same single-vector periods through GEM and our plant from zero current.

    Returns (max |Δi_d|, |Δi_q| [A], max |Δi_a|, |Δi_b|, |Δi_c| [A]) over all period ends.
    """
    plant = Plant(params, ts_s, DynoMechanics(speed_rpm), trace_dt_s=None)
    gem = GemPmsm(params, speed_rpm, ts_s, solver)
    ts_ns = [plant.ts_ns]
    worst_dq = worst_abc = 0.0
    for code in codes:
        plant.advance([code], ts_ns)
        ours = plant.sample()
        i_d, i_q, (i_a, i_b, i_c) = gem.step(code)
        worst_dq = max(worst_dq, abs(ours.i_d - i_d), abs(ours.i_q - i_q))
        worst_abc = max(worst_abc, abs(ours.i_a - i_a), abs(ours.i_b - i_b), abs(ours.i_c - i_c))
    return worst_dq, worst_abc


def run_plant_bench(periods: int = 20_000, repeats: int = 5, *, motor: str = "niu2020-ipmsm",
                    speed_rpm: float = 1500.0, ts_s: float = 100e-6, accuracy_periods: int = 2000,
                    include_gem: bool = True, seed: int = 2020) -> PlantBenchResult:
    """Measure our plant (single / three sub-intervals, trace on / off) and, if available, GEM."""
    for name, value in (("periods", periods), ("repeats", repeats), ("accuracy_periods", accuracy_periods)):
        if isinstance(value, bool) or not isinstance(value, int) or value < 1:
            raise ParameterError(f"benchmark '{name}' must be an integer ≥ 1, got {value!r}")
    if not math.isfinite(speed_rpm):
        raise ParameterError(f"benchmark speed must be finite, got {speed_rpm!r} rpm")
    params = load_pmsm(motor)
    ts_ns = Plant(params, ts_s, DynoMechanics(speed_rpm), trace_dt_s=None).ts_ns  # validates ts
    rng = np.random.default_rng(seed)
    single = single_vector_commands(periods, ts_ns, rng)
    three = three_vector_commands(periods, ts_ns, rng)
    result = PlantBenchResult(
        motor=params.name, speed_rpm=speed_rpm, ts_s=ts_s, periods=periods, repeats=repeats,
        accuracy_periods=accuracy_periods,
        periods_per_s_single=time_plant(params, speed_rpm, ts_s, single, None, repeats),
        periods_per_s_single_trace=time_plant(params, speed_rpm, ts_s, single, TRACE_DT_S, repeats),
        periods_per_s_three=time_plant(params, speed_rpm, ts_s, three, None, repeats),
        periods_per_s_three_trace=time_plant(params, speed_rpm, ts_s, three, TRACE_DT_S, repeats),
        periods_per_s_single_advance_only=time_plant(params, speed_rpm, ts_s, single, None, repeats,
                                                     with_sample=False),
    )
    version = gem_version() if include_gem else None
    if version is None:
        return result
    codes = [s[0] for s, _ in single]
    gem_rate = time_gem(params, speed_rpm, ts_s, codes, repeats)
    euler_rate = time_gem(params, speed_rpm, ts_s, codes, repeats, solver="euler")
    acc_rng = np.random.default_rng(seed + 1)
    acc_codes = [s[0] for s, _ in single_vector_commands(accuracy_periods, ts_ns, acc_rng)]
    di_dq, di_abc = gem_deviation(params, speed_rpm, ts_s, acc_codes)
    di_euler, _ = gem_deviation(params, speed_rpm, ts_s, acc_codes, solver="euler")
    return _with_gem(result, version, gem_rate, euler_rate, di_dq, di_abc, di_euler)


def _with_gem(r: PlantBenchResult, version: str, gem_rate: float, euler_rate: float, di_dq: float,
              di_abc: float, di_euler: float) -> PlantBenchResult:
    fields = asdict(r)
    fields.update(
        gem_version=version, gem_timing_method=GEM_TIMING_METHOD, gem_solver=GEM_SOLVERS["default"],
        gem_steps_per_s=gem_rate, gem_steps_per_s_euler=euler_rate,
        ratio_vs_gem=r.periods_per_s_single / gem_rate,
        ratio_vs_gem_trace=r.periods_per_s_single_trace / gem_rate,
        ratio_vs_gem_euler=r.periods_per_s_single / euler_rate,
        ratio_vs_gem_advance_only=r.periods_per_s_single_advance_only / gem_rate,
        gem_max_abs_di_a=di_dq, gem_max_abs_di_abc_a=di_abc, gem_euler_max_abs_di_a=di_euler,
    )
    return PlantBenchResult(**fields)


def format_result(r: PlantBenchResult) -> list[str]:
    """Human-readable lines of a benchmark result."""
    lines = [
        f"plant benchmark: {r.motor}, {r.speed_rpm:g} rpm (dyno), Ts = {r.ts_s * 1e6:g} µs, "
        f"{r.periods} periods × {r.repeats} repeats (median), advance + sample per period",
        f"  single-vector periods, trace off:      {r.periods_per_s_single:12,.0f} periods/s",
        f"  single-vector periods, trace 2 µs:     {r.periods_per_s_single_trace:12,.0f} periods/s",
        f"  three-sub-interval periods, trace off: {r.periods_per_s_three:12,.0f} periods/s",
        f"  three-sub-interval periods, trace 2 µs:{r.periods_per_s_three_trace:12,.0f} periods/s",
        f"  single-vector, trace off, advance only:{r.periods_per_s_single_advance_only:12,.0f} periods/s",
    ]
    if r.gem_steps_per_s is None:
        if not gem_installed():
            lines.append("  gym-electric-motor: not installed (pip install pmsm-hil[bench]); no comparison")
        else:
            lines.append("  gym-electric-motor: comparison skipped (--no-gem)")
        return lines
    lines += [
        f"gym-electric-motor {r.gem_version}, timed with {r.gem_timing_method}",
        f"  {r.gem_solver}: {r.gem_steps_per_s:12,.0f} steps/s  -> ours/theirs = {r.ratio_vs_gem:.1f}× "
        f"(trace on: {r.ratio_vs_gem_trace:.1f}×, advance only: {r.ratio_vs_gem_advance_only:.1f}×; "
        "goal ≥ 20×)",
        f"  {GEM_SOLVERS['euler']}: {r.gem_steps_per_s_euler:12,.0f} steps/s  -> "
        f"ours/theirs = {r.ratio_vs_gem_euler:.1f}×",
        f"  accuracy over {r.accuracy_periods} random single-vector periods: max |Δi_dq| GEM vs plant = "
        f"{r.gem_max_abs_di_a:.3f} A (default solver), {r.gem_euler_max_abs_di_a:.3f} A (Euler)",
        f"  phase currents as GEM reports them: max |Δi_abc| = {r.gem_max_abs_di_abc_a:.3f} A "
        "(GEM converts i_dq to abc with the step-start angle)",
    ]
    return lines
