"""Streaming window metrics: many blocks give the whole-array figures; quantiles are numpy's exactly; the
THD span is the end of the window; memory-bounded pieces keep what they promise."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pmsm_hil.hil.metrics import MetricsError, compute_run_metrics, current_thd, quantiles
from pmsm_hil.hil.metrics.moments import WeightedMoments
from pmsm_hil.hil.metrics.quantiles import IntQuantiles
from pmsm_hil.hil.metrics.streaming import WindowMetrics
from pmsm_hil.hil.metrics.thd import next_smooth
from pmsm_hil.hil.metrics.trace_tail import TraceTail
from pmsm_hil.hil.records import TRACE_DTYPE
from tests.metrics._signals import make_periods, make_trace, three_phase

TS = 100e-6
P = 4
OMEGA = 1500.0 * 2 * math.pi / 60.0
F1 = P * OMEGA / (2 * math.pi)
ARGS = {"ts_s": TS, "pole_pairs": P, "wall_time_s": 1.0, "link_stats": {}, "deadline_misses": 0}


def _run(duration: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    tr = make_trace(duration, 2e-6, OMEGA)
    tr["omega_m"] += rng.normal(0.0, 0.5, tr.shape[0])
    tr["i_a"], tr["i_b"], tr["i_c"] = three_phase(tr["t"], F1, {1: 10.0, 5: 0.5, 7: 0.3})
    tr["torque"] = 7.0 + 0.4 * np.sin(2 * np.pi * 3000.0 * tr["t"]) + rng.normal(0.0, 0.05, tr.shape[0])
    n = round(duration / TS)
    p = make_periods(n, TS)
    p["leg_transitions"] = rng.integers(0, 7, n)
    p["boundary_transitions"] = np.minimum(p["leg_transitions"], 1)
    p["exec_time_ns"] = rng.integers(500, 90_000, n)
    p["exec_split_ns"] = rng.integers(100, 30_000, (n, 3))
    p["candidates"] = rng.integers(1, 8, n)
    p["torque_ref"] = 7.0 + rng.normal(0.0, 0.01, n)
    return p, tr


def _blocks(arr: np.ndarray, cuts: list[int]) -> list[np.ndarray]:
    edges = sorted({0, arr.shape[0], *(c % max(arr.shape[0], 1) for c in cuts)})
    return [arr[a:b] for a, b in itertools.pairwise(edges)]


def _flat(m: dict[str, object], prefix: str = "") -> dict[str, object]:
    out: dict[str, object] = {}
    for k, v in m.items():
        if isinstance(v, dict):
            out.update(_flat(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


@settings(max_examples=15, deadline=None)
@given(st.lists(st.integers(min_value=1, max_value=10**6), max_size=12))
def test_any_block_split_gives_the_whole_array_metrics(cuts: list[int]) -> None:
    p, tr = _run(0.12)
    whole = _flat(compute_run_metrics(p, tr, **ARGS))
    acc = WindowMetrics()
    for block in _blocks(p, cuts):
        acc.add_periods(block)
    for block in _blocks(tr, [c * 7 for c in cuts]):
        acc.add_trace(block)
    streamed = _flat(acc.result(**ARGS))
    assert streamed.keys() == whole.keys()
    for key, value in whole.items():
        if isinstance(value, float):
            assert streamed[key] == pytest.approx(value, rel=1e-12, abs=1e-12), key
        else:
            assert streamed[key] == value, key


def test_a_block_that_is_all_cold_start_adds_no_execution_split() -> None:
    """A run that ends within its cold start (a trip at period 5) gives a block whose every period is cold."""
    p, _ = _run(0.01)
    acc = WindowMetrics()
    acc.add_periods(p[:5], cold=10)
    acc.add_periods(p[5:8], cold=2)
    assert acc.periods == 8


def test_exec_quantiles_are_numpys_exactly() -> None:
    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 10, 999, 4321):
        values = rng.integers(0, rng.integers(1, 200_000), n)
        acc = IntQuantiles(1e-3)
        for part in np.array_split(values, 5):
            acc.add(part)
        us = values.astype(np.float64) * 1e-3
        assert acc.median() == np.median(us)
        for q in (0.0, 1.0, 50.0, 99.0, 100.0):
            assert acc.percentile(q) == np.percentile(us, q)
        assert acc.maximum() == us.max()
    assert math.isnan(IntQuantiles().median())


@pytest.mark.parametrize("pending", [1, 7, 100])
def test_exec_quantiles_counted_in_many_folds(monkeypatch: pytest.MonkeyPatch, pending: int) -> None:
    # blocks larger and smaller than the pending buffer, values seen again in later folds
    monkeypatch.setattr(quantiles, "PENDING", pending)
    rng = np.random.default_rng(pending)
    values = rng.integers(0, 300, 2000).astype(np.uint32)
    acc = IntQuantiles(1e-3)
    for part in np.array_split(values, 37):
        acc.add(part)
    us = values.astype(np.float64) * 1e-3
    assert acc.n == values.shape[0] and acc.median() == np.median(us) and acc.maximum() == us.max()
    assert [acc.percentile(q) for q in (0.0, 3.0, 99.0)] == [np.percentile(us, q) for q in (0.0, 3.0, 99.0)]


def test_moments_of_one_sample_and_of_a_constant() -> None:
    one = WeightedMoments()
    one.add(np.array([0.5]), np.array([3.0]))
    assert (one.mean, one.rms_deviation, one.samples) == (3.0, 0.0, 1)
    flat = WeightedMoments()
    for k in range(4):
        t = np.arange(k * 10, k * 10 + 10) * 1e-6
        flat.add(t, np.full(10, 2.5))
    assert flat.mean == pytest.approx(2.5, rel=1e-15) and flat.rms_deviation == pytest.approx(0.0, abs=1e-12)


@settings(max_examples=30, deadline=None)
@given(st.lists(st.integers(min_value=1, max_value=3000), min_size=1, max_size=12), st.integers(0, 2**32 - 1))
def test_moments_in_blocks_are_the_trapezoid_formulas(sizes: list[int], seed: int) -> None:
    # non-uniform times, blocks of any size (single samples included): the textbook whole-array figures
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(1e-7, 2e-6, sum(sizes)))
    x = 7.0 + 0.4 * np.sin(2e4 * t) + rng.normal(0.0, 0.05, t.shape[0])
    acc = WeightedMoments()
    for a, b in itertools.pairwise(np.cumsum([0, *sizes])):
        acc.add(t[a:b], x[a:b])
    assert (acc.samples, acc.minimum, acc.maximum) == (x.shape[0], x.min(), x.max())
    if t.shape[0] == 1:
        assert (acc.mean, acc.rms_deviation) == (x[0], 0.0)
        return
    w = np.zeros_like(t)
    w[:-1] += np.diff(t) / 2.0
    w[1:] += np.diff(t) / 2.0
    mean = float(np.sum(w * x) / np.sum(w))
    assert acc.mean == pytest.approx(mean, rel=1e-14)
    assert acc.rms_deviation == pytest.approx(math.sqrt(np.sum(w * (x - mean) ** 2) / np.sum(w)), rel=1e-12)


def test_trace_tail_keeps_the_last_span_only() -> None:
    tail = TraceTail(TRACE_DTYPE, span_s=0.01)
    for k in range(50):
        block = make_trace(0.001 - 2e-6, 2e-6)
        block["t"] += k * 0.001
        tail.add(block)
        if k == 20:
            warm = tail._ring
    assert tail._ring is warm  # once the span is filled the ring is reused, not reallocated
    rows = tail.array()
    assert rows["t"][-1] == pytest.approx(0.05 - 2e-6)
    assert rows["t"][0] >= rows["t"][-1] - 0.01 - 1e-12
    assert rows["t"][0] <= rows["t"][-1] - 0.01 + 2e-6 + 1e-12
    assert tail.capacity <= 5000 + 3 * 500  # the span (5000 records) and a block or two, not 50 blocks


@settings(max_examples=25, deadline=None)
@given(st.lists(st.integers(min_value=1, max_value=9000), min_size=1, max_size=30),
       st.floats(min_value=0.0, max_value=0.02))
def test_trace_tail_is_the_last_span_of_the_whole_trace(sizes: list[int], span: float) -> None:
    # blocks of any size (shorter or longer than the span, the ring wrapping anywhere) keep exactly the
    # records a whole-trace cut keeps
    whole = make_trace(sum(sizes) * 2e-6, 2e-6)[: sum(sizes)]
    whole["i_a"] = np.arange(whole.shape[0])
    tail = TraceTail(TRACE_DTYPE, span_s=span)
    for a, b in itertools.pairwise(np.cumsum([0, *sizes])):
        tail.add(whole[a:b])
        expect = whole[: b][whole["t"][: b] >= whole["t"][b - 1] - span]
        assert np.array_equal(tail.array(), expect)


def test_thd_of_a_long_window_is_the_last_second() -> None:
    # 1.5 s: the first 0.5 s carries a 5th harmonic, the last second none; the THD sees only the last second
    tr = make_trace(1.5, 2e-6, OMEGA)
    tr["i_a"], tr["i_b"], tr["i_c"] = three_phase(tr["t"], F1, {1: 10.0})
    early = tr["t"] < 0.5 - 1e-9
    dirty = three_phase(tr["t"], F1, {5: 1.0})
    for ph, extra in zip(("i_a", "i_b", "i_c"), dirty, strict=True):
        tr[ph][early] += extra[early]
    p = make_periods(round(1.5 / TS), TS)
    m = compute_run_metrics(p, tr, **ARGS)
    assert m["current_thd_pct"] < 0.01
    whole = current_thd(tr["t"], tr["i_a"], F1)
    assert whole.thd_pct > 1.0  # over the whole window the harmonic would show


def test_fast_fft_lengths() -> None:
    assert next_smooth(6668) == 6750 and next_smooth(82) == 90 and next_smooth(1) == 1
    assert all(n <= next_smooth(n) < 2 * n for n in range(1, 3000))


def test_trace_blocks_out_of_order_are_refused() -> None:
    acc = WindowMetrics()
    tr = make_trace(0.001, 2e-6)
    acc.add_trace(tr)
    with pytest.raises(MetricsError, match=r"trace\.t"):
        acc.add_trace(tr)
