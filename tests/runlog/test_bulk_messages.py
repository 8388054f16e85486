"""`BulkMessages` writes the file `Writer.add_message` writes, byte for byte, whatever the chunk size."""

from __future__ import annotations

from pathlib import Path

import pytest

from pmsm_hil.hil.runlog import sink as sink_module
from pmsm_hil.hil.runlog.sink import McapSink
from tests.runlog._blocks import frame_block, period_block, trace_block


def _write(path: Path, bulk: bool) -> bytes:
    sink = McapSink(path, {"run": "bulk"}, "lz4")
    assert sink._bulk is not None  # the installed mcap is laid out as BulkMessages expects
    if not bulk:
        sink._bulk = None  # add_message per message
    for k in range(6):
        sink.write_periods(period_block(k * 700, 700).tobytes())
        sink.write_frames(frame_block(k * 700, 700).tobytes())
        sink.write_trace(trace_block(k * 700, 10).tobytes())
        if k == 3:
            sink.flush()
    sink.close()
    return path.read_bytes()


@pytest.mark.parametrize("chunk_bytes", [1, 5000, 200_000, sink_module.CHUNK_BYTES])
def test_bulk_messages_write_the_same_bytes_as_add_message(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                           chunk_bytes: int) -> None:
    monkeypatch.setattr(sink_module, "CHUNK_BYTES", chunk_bytes)
    assert _write(tmp_path / "bulk.mcap", True) == _write(tmp_path / "each.mcap", False)
