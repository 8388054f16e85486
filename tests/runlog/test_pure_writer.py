"""The logger's numpy-free encoders (`pure_writer`, `layouts`) write the bytes the numpy encoders write: the same
layouts, the same log times, the same MCAP file for the same blocks whichever encoders wrote it (numpy only, numpy
free only, or a switch mid-run), and a short run's logger process never loads numpy."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.records import FAULT_DTYPE, FRAME_DTYPE, PERIOD_DTYPE, TRACE_DTYPE, TRACE_DTYPE6
from pmsm_hil.hil.runlog import cdr, encoding, layouts, pure_writer
from pmsm_hil.hil.runlog import sink as sink_module
from pmsm_hil.hil.runlog.console import CONSOLE_DTYPE
from pmsm_hil.hil.runlog.logger import RunLogger
from pmsm_hil.hil.runlog.sink import McapSink
from tests.runlog._blocks import frame_block, period_block, trace_block


def _dtype(fields: tuple[layouts.Field, ...]) -> np.dtype:
    return np.dtype([(f.name, f.code, (f.length,)) if f.length else (f.name, f.code) for f in fields])


def test_the_layouts_are_the_record_dtypes_and_the_cdr_messages() -> None:
    assert _dtype(layouts.PERIOD_FIELDS) == PERIOD_DTYPE
    assert _dtype(layouts.FRAME_FIELDS) == FRAME_DTYPE
    assert _dtype(layouts.FAULT_FIELDS) == FAULT_DTYPE
    assert TRACE_DTYPE.names == layouts.TRACE_FIELDS
    for pure, numpy_msg in ((layouts.PERIOD_MSG, cdr.PERIOD_MSG), (layouts.FRAME_MSG, cdr.FRAME_MSG)):
        assert pure.schema == numpy_msg.schema
        assert pure.size == numpy_msg.dtype.itemsize
        assert [(s.name, s.offset) for s in pure.slots] == [(n, numpy_msg.dtype.fields[n][1])
                                                            for n in numpy_msg.dtype.names[1:]]
    assert layouts.FRAME_RENAMES == cdr.FRAME_RENAMES
    assert layouts.json_schema(layouts.FAULT_FIELDS, "link fault") == encoding.json_schema(FAULT_DTYPE, "link fault")
    assert layouts.ros2msg_schema(TRACE_DTYPE6.names) == encoding.ros2msg_schema(TRACE_DTYPE6)


def test_log_times_round_as_numpy_does() -> None:
    rng = np.random.default_rng(7)
    t = np.concatenate([
        [math.nan, math.inf, -math.inf, -1.0, -0.0, 0.0, 1e-12, 0.5e-9, 1.5e-9, 2.5e-9, 3.5e-9, 9e9, 9.1e9, 1e300],
        rng.uniform(0.0, 100.0, 2000), np.arange(2000) * 100e-6, np.arange(2000) * 2e-6 + 0.3,
    ])
    block = np.zeros(t.shape[0], dtype=PERIOD_DTYPE)
    block["t"] = t
    assert [pure_writer.log_time_ns(float(x)) for x in t] == encoding.periods_log_times_ns(block).tolist()


def _odd_blocks(k: int) -> tuple[np.ndarray, np.ndarray]:
    """A period block with NaN, ±inf and negative times, and frames with `length` past the data field and
    `is_fd` other than 0/1 (bytes the encoders must turn into what the numpy encoders write)."""
    periods = period_block(k * 300, 300)
    periods["t"][:4] = (math.nan, -1.0, math.inf, 5e9)
    periods["i_a"][5:9] = (math.nan, math.inf, -math.inf, -0.0)
    frames = frame_block(k * 300, 300)
    rng = np.random.default_rng(k)
    frames["length"] = rng.integers(0, 256, frames.shape[0])
    frames["is_fd"] = rng.integers(0, 256, frames.shape[0])
    frames["data"] = rng.integers(0, 256, frames["data"].shape)
    return periods, frames


def _write(path: Path, budgets: list[float], trace: np.dtype = TRACE_DTYPE, numpy_only: bool = False) -> bytes:
    """Rounds of periods, frames, trace (and a fault and a console line): round k with encoder budget `budgets[k]`
    (s of CPU; 0 = numpy, inf = numpy-free); `numpy_only`: every block through numpy's encoders (the trace's too)."""
    with pytest.MonkeyPatch.context() as mp:
        if numpy_only:
            mp.setattr(pure_writer, "LITTLE_ENDIAN", False)
        return _write_rounds(path, budgets, trace)


def _write_rounds(path: Path, budgets: list[float], trace: np.dtype) -> bytes:
    sink = McapSink(path, {"run": "pure"}, "lz4", trace.names)
    assert sink._bulk is not None
    for k, budget in enumerate(budgets):
        sink.pure_cpu_s = budget
        periods, frames = _odd_blocks(k)
        sink.write_periods(periods.tobytes())
        sink.write_frames(frames.tobytes())
        tr = np.zeros(500, dtype=trace)
        for i, name in enumerate(trace.names):
            tr[name] = trace_block(k * 10, 10)["t"] * (i + 1)
        tr["t"][0] = math.nan if k == 2 else tr["t"][0]
        sink.write_trace(tr.tobytes())
        sink.write_periods(period_block(5000 + k, 1).tobytes())  # a one-record block
        faults = np.zeros(2, dtype=FAULT_DTYPE)
        faults["t"], faults["seq"] = (k * 0.01, k * 0.01 + 1e-4), (k, k + 1)
        sink.write_faults(faults.tobytes())
        console = np.zeros(1, dtype=CONSOLE_DTYPE)
        console["t"], console["seq"], console["stream"], console["length"], console["text"] = k, k, 1, 5, b"hello"
        sink.write_console(console.tobytes())
        if k == 3:
            sink.flush()
    sink.close()
    return path.read_bytes()


@pytest.mark.parametrize("chunk_bytes", [1, 5000, 200_000, sink_module.CHUNK_BYTES])
def test_the_numpy_free_encoders_write_the_file_numpy_writes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                             chunk_bytes: int) -> None:
    monkeypatch.setattr(sink_module, "CHUNK_BYTES", chunk_bytes)
    numpy_only = _write(tmp_path / "numpy.mcap", [0.0] * 6, numpy_only=True)
    assert _write(tmp_path / "pure.mcap", [math.inf] * 6) == numpy_only
    assert _write(tmp_path / "switch.mcap", [math.inf, math.inf, 0.0, math.inf, 0.0, 0.0]) == numpy_only


def test_a_six_phase_trace_is_the_same_file(tmp_path: Path) -> None:
    numpy_only = _write(tmp_path / "numpy.mcap", [0.0] * 3, TRACE_DTYPE6, numpy_only=True)
    assert _write(tmp_path / "pure.mcap", [math.inf] * 3, TRACE_DTYPE6) == numpy_only


def _logged(path: Path, blocks: list[tuple[np.ndarray, np.ndarray, np.ndarray]]) -> dict[str, Any]:
    with RunLogger(path, metadata={"run": "x"}, flush_interval_s=3600.0) as lg:
        for periods, frames, trace in blocks:
            lg.submit_periods(periods)
            lg.submit_frames(frames)
            lg.submit_trace(trace)
    assert lg.final_stats is not None
    return lg.final_stats


def test_a_short_run_is_logged_without_numpy_and_writes_the_old_bytes(tmp_path: Path) -> None:
    """A run of 2000 periods through the logger process (its encoders numpy-free: numpy never loaded there) is
    byte for byte the file the numpy encoders write from the same blocks."""
    blocks = [(period_block(k * 1000, 1000), frame_block(k * 1000, 1000), trace_block(k * 1000, 1000))
              for k in range(2)]
    stats = _logged(tmp_path / "run.mcap", blocks)
    assert stats["periods"] == 2000 and stats["numpy"] is False
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pure_writer, "LITTLE_ENDIAN", False)  # the numpy encoders, as before
        sink = McapSink(tmp_path / "old.mcap", {"run": "x"}, "lz4")
        for periods, frames, trace in blocks:
            sink.write_periods(periods.tobytes())
            sink.write_frames(frames.tobytes())
            sink.write_trace(trace.tobytes())
        sink.close()
    assert (tmp_path / "run.mcap").read_bytes() == (tmp_path / "old.mcap").read_bytes()

