"""The per-block JSON encoder (`make_json_encoder`, /link_faults): fields constant over a block (written once
into the template) give the text of the plain per-record template."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.records import PERIOD_DTYPE
from pmsm_hil.hil.runlog import encoding
from tests.runlog._blocks import period_block


def _per_record(block: np.ndarray) -> list[bytes]:
    names = list(block.dtype.names or ())
    template = encoding._template(block.dtype, names)
    cols: list[list[Any]] = []
    for col in encoding._split_columns(block, names):
        values = col.tolist()
        cols.append(["null" if isinstance(v, float) and not math.isfinite(v) else v for v in values])
    return [(template % row).encode() for row in zip(*cols, strict=True)]


encode = encoding.make_json_encoder(PERIOD_DTYPE)  # the widest record dtype: every kind of field


@pytest.mark.parametrize("n", [1, 2, 300])
def test_constant_fields_give_the_per_record_text(n: int) -> None:
    b = period_block(0, n)
    b["load_torque"] = 7.25  # constant
    b["speed_ref"] = np.inf  # constant, non-finite: null
    b["i_u"] = np.nan  # constant NaN: null
    b["i_v"][: n // 2] = np.nan  # NaN in part
    b["torque_ref"][-1] = np.inf  # one non-finite value
    b["n_states"] = 3
    b["states"][:, 1] = 5  # one column of a sub-array field
    b["exec_split_ns"] = 1234
    assert encode(b) == _per_record(b)
    assert encode(np.zeros(4, PERIOD_DTYPE)) == _per_record(np.zeros(4, PERIOD_DTYPE))
    assert encode(b[:0]) == []
