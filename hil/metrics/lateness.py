"""The real-time lateness histogram: how late the period starts were, in fixed bins [µs] spanning the
microseconds a tuned loop keeps to the milliseconds a scheduler stall costs."""

from __future__ import annotations

from typing import Any

import numpy as np
from pmsm_hil.hil.metrics.quantiles import IntQuantiles

#: bin edges [µs]; the last bin is everything from 10 ms on
LATENESS_EDGES_US = (0.0, 1.0, 2.0, 5.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0, 2000.0, 5000.0, 10000.0)


def lateness_histogram(lateness_ns: IntQuantiles) -> dict[str, Any]:
    """`{edges_us, counts}`: counts[i] period starts with lateness in [edges_us[i], edges_us[i+1]) µs, the last
    bin open-ended (from the last edge on)."""
    edges_ns = np.array([*(round(e * 1e3) for e in LATENESS_EDGES_US), np.iinfo(np.int64).max], dtype=np.int64)
    counts = lateness_ns.histogram(edges_ns)
    return {"edges_us": list(LATENESS_EDGES_US), "counts": [int(c) for c in counts]}
