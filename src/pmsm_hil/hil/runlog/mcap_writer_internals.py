"""The one place that reads mcap's private `Writer` state (for `BulkMessages`).

mcap's `Writer` has no public call to add many messages at once, so `BulkMessages` writes into the open chunk
itself: the Writer's chunk builder, statistics, chunk size and chunk-finalising method (name-mangled
`_Writer__…` attributes), and the chunk builder's and statistics' public fields. This module reaches them and
checks that every one is there; `tests/runlog/test_mcap_writer_internals.py` fails with one message naming what
is missing when an mcap release changes them. The versions checked are `TESTED_MCAP`, the range pyproject.toml
pins.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Final

from mcap.writer import Writer

from pmsm_hil.dist_version import installed_version
from pmsm_hil.hil.runlog.errors import RunLogError

#: the mcap versions whose private Writer state this module was checked against (pyproject.toml's pin)
TESTED_MCAP: Final = "mcap>=1.5,<1.7"
#: the Writer's private attributes read, by their name in mcap's writer.py
WRITER_FIELDS: Final = ("__chunk_builder", "__statistics", "__chunk_size", "__finalize_chunk")
#: fields of the chunk builder (mcap/_chunk_builder.py `ChunkBuilder`) read and updated
CHUNK_FIELDS: Final = ("count", "record_writer", "message_start_time", "message_end_time", "message_indices",
                       "num_messages")
#: fields of the Writer's `Statistics` record read and updated
STATISTICS_FIELDS: Final = ("message_start_time", "message_end_time", "channel_message_counts", "message_count")


class McapLayoutError(RunLogError):
    """The installed mcap's Writer is not laid out as `BulkMessages` expects (fields named in the message)."""


@dataclass(frozen=True, slots=True)
class WriterInternals:
    """A chunked Writer's private state: its open chunk, its statistics, its chunk size [bytes] and the method
    that writes the open chunk out."""

    chunk: Any
    statistics: Any
    chunk_size: int
    finalize_chunk: Callable[[], None]


def mcap_version() -> str:
    """The installed mcap's version ("unknown" when its metadata is missing)."""
    return installed_version("mcap", "unknown")


def missing_fields(writer: Writer) -> list[str]:
    """The private fields `writer_internals` needs that `writer` lacks ([] when all are there)."""
    missing = [f"Writer.{name}" for name in WRITER_FIELDS if not hasattr(writer, "_Writer" + name)]
    chunk = getattr(writer, "_Writer__chunk_builder", None)
    stats = getattr(writer, "_Writer__statistics", None)
    if chunk is not None:
        missing += [f"ChunkBuilder.{name}" for name in CHUNK_FIELDS if not hasattr(chunk, name)]
    if stats is not None:
        missing += [f"Statistics.{name}" for name in STATISTICS_FIELDS if not hasattr(stats, name)]
    return missing


def layout_problem(writer: Writer) -> str | None:
    """One line saying which private fields of the installed mcap are missing, or None when all are there."""
    missing = missing_fields(writer)
    if not missing:
        return None
    return (f"mcap {mcap_version()} changed the Writer's private fields BulkMessages uses (missing: "
            f"{', '.join(missing)}); install mcap in the tested range {TESTED_MCAP!r} or update "
            "src/pmsm_hil/hil/runlog/mcap_writer_internals.py")


def writer_internals(writer: Writer) -> WriterInternals:
    """The private state of a chunked `writer`; McapLayoutError naming what is missing, or saying the writer
    does not chunk."""
    problem = layout_problem(writer)
    if problem is not None:
        raise McapLayoutError(problem)
    private: Any = writer
    chunk = private._Writer__chunk_builder
    if chunk is None:
        raise McapLayoutError("mcap Writer without chunks (use_chunking=False): no chunk to add messages to")
    return WriterInternals(chunk=chunk, statistics=private._Writer__statistics,
                           chunk_size=int(private._Writer__chunk_size), finalize_chunk=private._Writer__finalize_chunk)
