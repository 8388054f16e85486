"""RunLogger round trip: what is submitted is what is read back; the file is a complete MCAP."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from mcap.reader import make_reader

from pmsm_hil.hil.records import PERIOD_DTYPE
from pmsm_hil.hil.runlog import RunLogError, RunLogger, read_frames, read_metadata, read_periods, read_trace
from tests.runlog._blocks import frame_block, period_block, trace_block


def assert_records_equal(a: np.ndarray, b: np.ndarray) -> None:
    assert a.dtype == b.dtype and a.shape == b.shape
    for name in a.dtype.names or ():
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_round_trip_identical_values(tmp_path: Path, compression: str) -> None:
    path = tmp_path / "run.mcap"
    periods = np.concatenate([period_block(k, 500) for k in range(0, 3000, 500)])
    periods["i_d"][7] = np.nan  # JSON null, read back as NaN
    frames = frame_block(0, 300)
    trace = np.concatenate([trace_block(0, 100), trace_block(100, 100)])
    with RunLogger(path, metadata={"controller": "fcs-mpc-1", "ts": "1e-4"}, compression=compression) as lg:
        for k in range(0, 3000, 500):
            lg.submit_periods(periods[k : k + 500])
        lg.submit_frames(frames)
        lg.submit_trace(trace[:5000])
        lg.submit_trace(trace[5000:])
        lg.submit_periods(np.zeros(0, dtype=PERIOD_DTYPE))  # empty blocks are ignored
    assert lg.final_stats is not None and lg.final_stats["periods"] == 3000
    assert_records_equal(read_periods(path), periods)
    assert_records_equal(read_frames(path), frames)
    assert_records_equal(read_trace(path), trace)
    assert read_metadata(path) == {"controller": "fcs-mpc-1", "ts": "1e-4"}


def test_file_is_complete_indexed_mcap_with_cdr_channels(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    with RunLogger(path, metadata={"a": "b"}) as lg:
        lg.submit_periods(period_block(0, 100))
        lg.submit_frames(frame_block(0, 10))
        lg.submit_trace(trace_block(0, 10))
    with path.open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None and summary.statistics is not None
        topics = {ch.topic: ch for ch in summary.channels.values()}
        assert set(topics) == {"/periods", "/frames", "/trace", "/run/metadata", "/link_faults", "/target/console",
                               "/board/periods"}
        for name in ("/periods", "/frames", "/trace"):
            assert topics[name].message_encoding == "cdr"
            assert summary.schemas[topics[name].schema_id].encoding == "ros2msg"
        assert topics["/link_faults"].message_encoding == "json"
        assert topics["/target/console"].message_encoding == "json"
        assert topics["/board/periods"].message_encoding == "json"
        counts = summary.statistics.channel_message_counts
        assert counts[topics["/periods"].id] == 100 and counts[topics["/frames"].id] == 20
        periods = [m for _, _, m in reader.iter_messages(topics=["/periods"])]
        assert periods[0].log_time == 0 and periods[0].sequence == 0 and periods[1].sequence == 1
        assert {len(m.data) for m in periods} == {252}  # fixed size: header + PERIOD_DTYPE fields, aligned
        frames = [m for _, _, m in reader.iter_messages(topics=["/frames"])]
        assert {len(m.data) for m in frames} == {90} and frames[0].data[:4] == b"\x00\x01\x00\x00"


def test_log_time_is_sim_time_ns(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    with RunLogger(path, metadata={}) as lg:
        lg.submit_periods(period_block(1234, 10))
    with path.open("rb") as f:
        times = [m.log_time for _, _, m in make_reader(f).iter_messages(topics=["/periods"])]
    assert times == [round((1234 + k) * 100e-6 * 1e9) for k in range(10)]


def test_bad_arguments_are_clear_errors(tmp_path: Path) -> None:
    with pytest.raises(RunLogError, match="path"):
        RunLogger(tmp_path / "missing_dir" / "x.mcap", metadata={})
    with pytest.raises(RunLogError, match=r"metadata\['k'\]"):
        bad_metadata: Any = {"k": 1}
        RunLogger(tmp_path / "x.mcap", metadata=bad_metadata)
    with pytest.raises(RunLogError, match="flush_interval_s"):
        RunLogger(tmp_path / "x.mcap", metadata={}, flush_interval_s=0.0)
    with RunLogger(tmp_path / "x.mcap", metadata={}) as lg:
        with pytest.raises(RunLogError, match="periods"):
            lg.submit_periods(trace_block(0, 1))
        with pytest.raises(RunLogError, match="trace"):
            lg.submit_trace(period_block(0, 1))
    with pytest.raises(RunLogError, match="closed"):
        lg.submit_periods(period_block(0, 1))
    lg.close()  # idempotent


def test_ring_smaller_than_block_splits_and_waits(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    periods = period_block(0, 5000)  # ≈ 710 kB through a 64 kB ring
    with RunLogger(path, metadata={}, ring_bytes=64 * 1024) as lg:
        lg.submit_periods(periods)
    assert_records_equal(read_periods(path), periods)
