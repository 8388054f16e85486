"""The real-time lateness statistics in fixed memory: the histogram (`lateness_histogram_us`, exact) and the
quantiles (`lateness_us`, within the stated relative error of numpy's)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pmsm_hil.hil.metrics.lateness import LATENESS_EDGES_US, US_BINS, LatenessStats, lateness_histogram
from pmsm_hil.hil.metrics.log_quantiles import RELATIVE_ERROR, LogQuantiles


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(min_value=-5_000, max_value=50_000_000), min_size=0, max_size=3000),
       st.integers(min_value=1, max_value=700))
def test_histogram_equals_numpy_for_any_block_split(values: list[int], block: int) -> None:
    q = LatenessStats()
    arr = np.array(values, dtype=np.int64)
    for k in range(0, arr.shape[0], block):
        q.add(arr[k:k + block])
    got = lateness_histogram(q)
    edges_ns = np.array([e * 1e3 for e in LATENESS_EDGES_US] + [np.inf])
    clipped = np.clip(arr.astype(np.float64), 0.0, None)  # early starts count in the first bin
    expected, _ = np.histogram(clipped, bins=edges_ns)
    assert got["edges_us"] == list(LATENESS_EDGES_US)
    assert got["counts"] == [int(c) for c in expected]
    assert sum(got["counts"]) == len(values)


def test_bin_edges_are_half_open() -> None:
    q = LatenessStats()
    q.add(np.array([0, 999, 1000, 1999, 2000, 10_000_000, 10_000_001], dtype=np.int64))
    counts = lateness_histogram(q)["counts"]
    assert counts[:3] == [2, 2, 1]  # [0, 1) µs, [1, 2) µs, [2, 5) µs
    assert counts[-1] == 2  # from 10 ms on


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(min_value=-1_000, max_value=2**40), min_size=1, max_size=2000),
       st.sampled_from([0.0, 1.0, 10.0, 50.0, 90.0, 99.0, 99.99, 100.0]))
def test_quantiles_are_within_the_stated_error_of_numpy(values: list[int], q: float) -> None:
    arr = np.array(values, dtype=np.int64)
    acc = LogQuantiles(1e-3)
    for k in range(0, arr.shape[0], 333):
        acc.add(arr[k:k + 333])
    exact = float(np.percentile(np.clip(arr, 0, None).astype(np.float64), q)) * 1e-3
    assert abs(acc.percentile(q) - exact) <= RELATIVE_ERROR * exact + 1e-12
    assert acc.maximum() == max(0, int(arr.max())) * 1e-3
    assert acc.n == arr.shape[0]


def test_small_values_are_exact() -> None:
    arr = np.array([3, 7, 7, 100, 255, 0, 12], dtype=np.int64)
    acc = LogQuantiles()
    acc.add(arr)
    for q in (0.0, 25.0, 50.0, 75.0, 100.0):
        assert acc.percentile(q) == float(np.percentile(arr, q))
    assert acc.median() == float(np.median(arr))


def test_memory_does_not_grow_with_distinct_values() -> None:
    """Ten blocks of 100 000 distinct values each: the same arrays, the same size, before and after."""
    acc = LatenessStats()
    sizes = {id(acc._counts): acc._counts.nbytes, id(acc._per_us): acc._per_us.nbytes}
    rng = np.random.default_rng(1)
    for _ in range(10):
        acc.add(rng.integers(0, 50_000_000, 100_000))
    assert {id(acc._counts): acc._counts.nbytes, id(acc._per_us): acc._per_us.nbytes} == sizes
    assert acc.n == 1_000_000


def test_histogram_edges_must_be_whole_microseconds() -> None:
    acc = LatenessStats()
    acc.add(np.array([1500, 2500, 10**12], dtype=np.int64))
    assert list(acc.histogram(np.array([0, 1000, 2000, 3000]))) == [0, 1, 2]  # from the last edge on: the last bin
    assert list(acc.histogram(np.array([0, 2000, np.iinfo(np.int64).max]))) == [1, 2]
    with pytest.raises(ValueError, match="whole µs"):
        acc.histogram(np.array([0, 1500, 3000]))
    with pytest.raises(ValueError, match="whole µs"):
        acc.histogram(np.array([0, (US_BINS + 1) * 1000]))
