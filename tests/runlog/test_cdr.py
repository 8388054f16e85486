"""Fixed-size CDR /periods and /frames: the schema in the file describes the bytes (checked by a decoder
written here from the ros2msg text and the CDR rules alone), NaN stays NaN, malformed messages are errors."""

from __future__ import annotations

import re
import struct
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader

from pmsm_hil.hil.records import FRAME_DTYPE, PERIOD_DTYPE
from pmsm_hil.hil.runlog import McapFormatError, RunLogger, cdr, read_frames, read_periods
from tests.runlog._blocks import frame_block, period_block

_STRUCT = {"float64": "d", "float32": "f", "uint64": "Q", "int64": "q", "uint32": "I", "int32": "i",
           "uint16": "H", "int16": "h", "uint8": "B", "int8": "b", "bool": "?"}


def decode_by_schema(schema: str, data: bytes) -> dict[str, Any]:
    """Sequential CDR reader: little-endian header, each primitive aligned to its size from the end of the
    header, fixed arrays as consecutive elements. Checks the message is used up exactly."""
    assert data[:4] == b"\x00\x01\x00\x00"
    pos, out = 0, {}
    body = data[4:]
    for line in schema.splitlines():
        line = line.split("#")[0].strip()
        if not line:
            continue
        m = re.fullmatch(r"(\w+)(?:\[(\d+)\])? (\w+)", line)
        assert m is not None, line
        code = "<" + _STRUCT[m.group(1)]
        size = struct.calcsize(code)
        pos += -pos % size
        count = int(m.group(2) or 0)
        values = [struct.unpack_from(code, body, pos + k * size)[0] for k in range(max(count, 1))]
        out[m.group(3)] = values if count else values[0]
        pos += size * max(count, 1)
    assert pos == len(body)
    return out


def _messages(path: Path, topic: str) -> tuple[str, list[bytes]]:
    with path.open("rb") as f:
        reader = make_reader(f)
        msgs = list(reader.iter_messages(topics=[topic]))
        assert msgs and msgs[0][1].message_encoding == "cdr" and msgs[0][0] is not None
        assert msgs[0][0].encoding == "ros2msg"
        return msgs[0][0].data.decode(), [m.data for _, _, m in msgs]


def _same_value(a: Any, b: Any) -> bool:
    return bool(np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True))


def test_messages_decode_by_their_schema_alone(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    periods = period_block(0, 50)
    periods["i_d"][3] = np.nan
    periods["torque"][4] = -np.inf
    frames = frame_block(0, 25)
    frames["length"][5] = 3
    with RunLogger(path, metadata={}) as lg:
        lg.submit_periods(periods)
        lg.submit_frames(frames)
    schema, data = _messages(path, "/periods")
    for rec, msg in zip(periods, data, strict=True):
        got = decode_by_schema(schema, msg)
        assert set(got) == set(PERIOD_DTYPE.names or ())
        for name, value in got.items():
            assert _same_value(value, rec[name]), name
    assert np.signbit(decode_by_schema(schema, data[4])["torque"])  # -inf written as is (JSON had null)
    schema, data = _messages(path, "/frames")
    names = {"dir": "direction", "id": "arbitration_id", "fd": "is_fd", "len": "length"}
    for rec, msg in zip(frames, data, strict=True):
        got = decode_by_schema(schema, msg)
        assert [names.get(k, k) for k in got] == list(FRAME_DTYPE.names or ())
        for name, value in got.items():
            assert _same_value(value, rec[names.get(name, name)]), name
    assert decode_by_schema(schema, data[5])["len"] == 3


def test_nan_and_inf_read_back_bit_for_bit(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    periods = period_block(0, 20)
    periods["i_q"][1] = np.inf
    periods["i_a"][2] = np.float64(np.nan) * -1.0  # a NaN with its sign bit set
    frames = frame_block(0, 10)
    frames["t"][3] = np.nan
    with RunLogger(path, metadata={}) as lg:
        lg.submit_periods(periods)
        lg.submit_frames(frames)
    assert read_periods(path).tobytes() == periods.tobytes()
    assert read_frames(path).tobytes() == frames.tobytes()


def test_frame_length_clamped_and_fd_as_bool() -> None:
    block = frame_block(0, 3)
    block["length"][0] = 200  # longer than the data field: clamped, as in the JSON logs
    block["is_fd"][1] = 7
    out = np.zeros(block.shape[0], dtype=cdr.FRAME_MSG.dtype)
    cdr.fill_frames(out, block)
    assert out["len"][0] == 64 and out["fd"][1]
    assert out.view(np.uint8).reshape(3, -1)[1, 24] == 1  # the byte itself is 0/1


def test_schema_parser_and_malformed_messages() -> None:
    msg = cdr.parse_schema(b"# c\nuint8 a  # note\nfloat64 b\nuint16[2] c\nint32 K=5\n", "/x")
    assert msg.dtype.fields is not None
    assert [msg.dtype.fields[n][1] for n in ("a", "b", "c")] == [4, 12, 20] and msg.dtype.itemsize == 24
    for bad in (b"string s\n", b"float64[] v\n", b"", b"uint8[<=3] v\n"):
        with pytest.raises(McapFormatError, match="/x"):
            cdr.parse_schema(bad, "/x")
    good = np.zeros(2, dtype=cdr.PERIOD_MSG.dtype)
    cdr.fill_periods(good, period_block(0, 2))
    raw = [good[k : k + 1].tobytes() for k in range(2)]
    with pytest.raises(McapFormatError, match="sizes"):
        cdr.decode([raw[0], raw[1][:-1]], cdr.PERIOD_MSG, PERIOD_DTYPE, {}, "/periods")
    with pytest.raises(McapFormatError, match="little-endian"):
        cdr.decode([b"\x01\x00\x00\x00" + raw[0][4:]], cdr.PERIOD_MSG, PERIOD_DTYPE, {}, "/periods")
