"""Message encodings: JSON text is valid JSON (NaN → null), CDR trace round trip, schemas parse.

(The fixed-size CDR /periods and /frames messages: test_cdr.py.)"""

from __future__ import annotations

import json

import numpy as np
import pytest

from pmsm_hil.hil.records import PERIOD_DTYPE, TRACE_DTYPE
from pmsm_hil.hil.runlog import McapFormatError
from pmsm_hil.hil.runlog import encoding as enc
from tests.runlog._blocks import period_block, trace_block


def test_record_json_is_valid_and_exact() -> None:
    block = period_block(5, 20)  # the widest record dtype through the JSON encoder /link_faults uses
    block["torque"][3] = np.inf
    block["omega_m"][4] = np.nan
    msgs = enc.make_json_encoder(PERIOD_DTYPE)(block)
    rows = [json.loads(m) for m in msgs]  # strict JSON: no NaN/Infinity literals
    assert rows[3]["torque"] is None and rows[4]["omega_m"] is None
    assert rows[0]["i_a"] == block["i_a"][0] and rows[0]["states"] == block["states"][0].tolist()
    back = enc.decode_json_records(msgs, PERIOD_DTYPE, "/periods")
    np.testing.assert_array_equal(back["i_b"], block["i_b"])
    assert np.isnan(back["torque"][3]) and np.isnan(back["omega_m"][4])


def test_cdr_trace_round_trip_and_layout() -> None:
    block = trace_block(3, 7)
    data = enc.encode_trace_cdr(block)
    assert data[:4] == b"\x00\x01\x00\x00"
    assert len(data) == 4 + len(TRACE_DTYPE.names or ()) * (8 + 8 * block.shape[0])
    back = enc.decode_trace_cdr(data)
    for name in TRACE_DTYPE.names or ():
        np.testing.assert_array_equal(back[name], block[name])
    with pytest.raises(McapFormatError, match="trace"):
        enc.decode_trace_cdr(data[:-8])


def test_schemas() -> None:
    schema = json.loads(enc.json_schema(PERIOD_DTYPE, "period"))
    assert schema["properties"]["states"]["type"] == "array"
    assert schema["properties"]["i_a"]["type"] == ["number", "null"]
    assert set(schema["properties"]) == set(PERIOD_DTYPE.names or ())
    msg = enc.ros2msg_schema(TRACE_DTYPE).decode()
    assert "float64[] i_a" in msg and "float64[] omega_m" in msg


def test_log_times_clamped() -> None:
    block = period_block(0, 3)
    block["t"] = [-1.0, np.nan, 2.5]
    assert enc.periods_log_times_ns(block).tolist() == [0, 0, 2_500_000_000]
