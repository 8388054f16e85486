"""mcap's private Writer state that `BulkMessages` writes into (src/pmsm_hil/hil/runlog/mcap_writer_internals.py):
present in the installed mcap, within the range pyproject.toml pins, and a change named in one line."""

from __future__ import annotations

import re
import tomllib
from io import BytesIO
from pathlib import Path

import pytest
from mcap.writer import Writer

from pmsm_hil.hil.runlog.bulk_messages import BulkMessages
from pmsm_hil.hil.runlog.mcap_writer_internals import (
    TESTED_MCAP,
    McapLayoutError,
    layout_problem,
    mcap_version,
    writer_internals,
)

ROOT = Path(__file__).resolve().parents[2]


def _release(text: str) -> tuple[int, ...]:
    return tuple(int(part) for part in re.findall(r"\d+", text)[:3])


def test_the_installed_mcap_has_every_private_field_bulk_messages_uses() -> None:
    """Fails with one line naming the missing fields when an mcap upgrade changes the Writer's private state."""
    problem = layout_problem(Writer(BytesIO()))
    assert problem is None, problem
    state = writer_internals(Writer(BytesIO(), chunk_size=4096))
    assert state.chunk_size == 4096
    assert state.chunk.count == 0 and state.statistics.message_count == 0


def test_the_installed_mcap_is_in_the_tested_range_pyproject_pins() -> None:
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    assert TESTED_MCAP in deps, f"pyproject.toml pins {[d for d in deps if 'mcap' in d]}, the adapter {TESTED_MCAP}"
    low, high = (_release(b) for b in TESTED_MCAP.split(","))
    assert low <= _release(mcap_version()) < high, (
        f"mcap {mcap_version()} is outside the tested range {TESTED_MCAP}: run tests/runlog and widen the pin")


def test_a_changed_writer_is_one_line_naming_the_fields_and_bulk_messages_steps_aside() -> None:
    writer = Writer(BytesIO())
    del writer._Writer__chunk_size  # type: ignore[attr-defined]
    del writer._Writer__chunk_builder.num_messages  # type: ignore[attr-defined]
    problem = layout_problem(writer)
    assert problem is not None and "\n" not in problem
    assert "Writer.__chunk_size" in problem and "ChunkBuilder.num_messages" in problem and TESTED_MCAP in problem
    with pytest.raises(McapLayoutError, match=r"missing: Writer\.__chunk_size"):
        writer_internals(writer)
    assert BulkMessages.of(writer) is None  # the sink then adds message by message


def test_a_writer_without_chunks_has_no_bulk_messages() -> None:
    writer = Writer(BytesIO(), use_chunking=False)
    with pytest.raises(McapLayoutError, match="without chunks"):
        writer_internals(writer)
    assert BulkMessages.of(writer) is None
