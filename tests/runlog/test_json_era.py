"""Logs written before /periods and /frames became CDR (JSON messages, `jsonschema` schemas) still read.

`data/json_era.mcap` was written by `McapSink` at commit fd6ad8c (the last JSON-era logger) from
`json_era_blocks()`; non-finite floats are JSON `null` there and read back as NaN.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from mcap.reader import make_reader

from pmsm_hil.hil.records import FRAME_DTYPE, PERIOD_DTYPE
from pmsm_hil.hil.runlog import read_frames, read_periods

DATA = Path(__file__).parent / "data" / "json_era.mcap"


def json_era_blocks() -> tuple[np.ndarray, np.ndarray]:
    """The periods (30) and frames (20) of `data/json_era.mcap`, from arithmetic only (no RNG stream)."""
    periods = np.zeros(30, dtype=PERIOD_DTYPE)
    k = np.arange(30)
    periods["seq"] = 100 + k
    periods["t"] = periods["seq"] * 100e-6
    for j, name in enumerate(PERIOD_DTYPE.names or ()):
        if name in ("t", "seq", "n_duties", "duties"):  # duties came after the JSON era: absent, read as 0
            continue
        field = periods[name]
        width = field.shape[1] if field.ndim == 2 else 1
        base = (k[:, None] * 7 + j * 3 + np.arange(width)[None, :]).reshape(field.shape)
        if field.dtype.kind == "f":
            periods[name] = base / 3.0 - 11.1  # not exact in decimal: repr round trip
        else:
            periods[name] = (base * 977) % (int(np.iinfo(field.dtype).max) + 1)
    periods["i_d"][4] = np.nan
    periods["torque"][5] = np.inf
    periods["i_x"] = np.nan  # a constant non-finite column
    frames = np.zeros(20, dtype=FRAME_DTYPE)
    n = np.arange(20)
    frames["t"] = (100 + n // 2) * 100e-6
    frames["seq"] = 200 + n
    frames["direction"] = n % 2
    frames["arbitration_id"] = 0x100 + n
    frames["is_fd"] = (n // 2) % 2
    frames["length"] = np.where(frames["is_fd"] == 1, 64, n % 9)
    for i in range(20):
        frames["data"][i, : frames["length"][i]] = (i * 13 + np.arange(frames["length"][i])) % 256
    return periods, frames


def _same(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype == b.dtype and a.shape == b.shape
    for name in a.dtype.names or ():
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)  # NaN equals NaN here


def test_json_era_file_reads_as_before() -> None:
    with DATA.open("rb") as f:
        summary = make_reader(f).get_summary()
    assert summary is not None
    encodings = {ch.topic: ch.message_encoding for ch in summary.channels.values()}
    assert encodings["/periods"] == "json" and encodings["/frames"] == "json"  # really a JSON-era file
    periods, frames = json_era_blocks()
    got = read_periods(DATA)
    assert np.isnan(got["i_d"][4]) and np.isnan(got["torque"][5])  # JSON null → NaN (inf was null too)
    periods["torque"][5] = np.nan
    _same(got, periods)
    _same(read_frames(DATA), frames)
