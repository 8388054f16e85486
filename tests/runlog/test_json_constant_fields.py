"""Per-block JSON encoders: fields constant over a block (written once into the template) and the frames'
payload slices give the text of the plain per-record template."""

from __future__ import annotations

import numpy as np
import pytest
from pmsm_hil.hil.records import FRAME_DTYPE, PERIOD_DTYPE
from pmsm_hil.hil.runlog import encoding

from tests.runlog._blocks import frame_block, period_block


def _per_record(block: np.ndarray) -> list[bytes]:
    names = list(block.dtype.names or ())
    template = encoding._template(block.dtype, names)
    return [(template % row).encode() for row in zip(*encoding._flat_columns(block, names), strict=True)]


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
    assert encoding.encode_periods(b) == _per_record(b)
    assert encoding.encode_periods(np.zeros(4, PERIOD_DTYPE)) == _per_record(np.zeros(4, PERIOD_DTYPE))
    assert encoding.encode_periods(b[:0]) == []


def test_frame_text_payload_and_length() -> None:
    fr = frame_block(0, 30)
    fr["length"][::4] = 200  # longer than the payload field: clamped to it
    fr["length"][1] = 0
    fr["t"][2] = np.nan
    fr["data"] = np.arange(FRAME_DTYPE["data"].shape[0], dtype=np.uint8)
    for msg, rec in zip(encoding.encode_frames(fr), fr, strict=True):
        n = min(int(rec["length"]), FRAME_DTYPE["data"].shape[0])
        t = "null" if np.isnan(rec["t"]) else repr(float(rec["t"]))
        expect = (f'{{"t":{t},"seq":{rec["seq"]},"dir":{rec["direction"]},"id":{rec["arbitration_id"]},'
                  f'"fd":{"true" if rec["is_fd"] else "false"},"len":{n},"data":"{rec["data"][:n].tobytes().hex()}"}}')
        assert msg == expect.encode()
    assert encoding.encode_frames(fr[:0]) == []
