"""The real-time lateness histogram (`lateness_histogram_us`)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from pmsm_hil.hil.metrics.lateness import LATENESS_EDGES_US, lateness_histogram
from pmsm_hil.hil.metrics.quantiles import IntQuantiles


@settings(max_examples=50, deadline=None)
@given(st.lists(st.integers(min_value=-5_000, max_value=50_000_000), min_size=0, max_size=3000),
       st.integers(min_value=1, max_value=700))
def test_histogram_equals_numpy_for_any_block_split(values: list[int], block: int) -> None:
    q = IntQuantiles(1e-3)
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
    q = IntQuantiles(1e-3)
    q.add(np.array([0, 999, 1000, 1999, 2000, 10_000_000, 10_000_001], dtype=np.int64))
    counts = lateness_histogram(q)["counts"]
    assert counts[:3] == [2, 2, 1]  # [0, 1) µs, [1, 2) µs, [2, 5) µs
    assert counts[-1] == 2  # from 10 ms on
