"""One configuration run by the test suite's Python reference loop and by the C loop, and their period records
compared field by field (all but the measured timings, bit for bit)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig

#: period record fields the firmware measures (wall time), which no two runs share
TIMING_FIELDS = frozenset({"exec_time_ns", "exec_split_ns"})


def reference_and_c_records(cfg: RunConfig) -> tuple[np.ndarray, np.ndarray]:
    """Every period record of `cfg` run by the reference loop and by the C loop (checked: which loop ran)."""
    runs = [run_closed_loop(replace(cfg, loop=loop)) for loop in ("python", "native")]
    assert [r.metrics["loop"] for r in runs] == ["python", "native"]
    py, na = (r.outcome.periods.all() for r in runs)
    return py, na


def assert_bit_identical(py: np.ndarray, na: np.ndarray) -> None:
    """The same records, every field but TIMING_FIELDS byte for byte."""
    assert py.shape == na.shape
    for name in py.dtype.names or ():
        if name not in TIMING_FIELDS:
            assert py[name].tobytes() == na[name].tobytes(), name
