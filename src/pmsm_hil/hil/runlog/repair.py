"""`repair_mcap`: rewrite the valid prefix of a (possibly truncated) MCAP file as a complete MCAP file."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from mcap.records import Channel, Message, Metadata, Schema
from mcap.writer import CompressionType, Writer

from pmsm_hil.hil.atomic_write import atomic_path, refuse_existing, same_file
from pmsm_hil.hil.runlog.errors import McapFormatError
from pmsm_hil.hil.runlog.reader import ScanState, scan_records


@dataclass
class RepairReport:
    """Outcome of a repair: sizes (bytes), whether the source was complete, what was recovered."""

    src_bytes: int
    valid_bytes: int
    source_complete: bool
    chunks: int
    messages: int
    messages_per_topic: dict[str, int] = field(default_factory=dict)
    metadata_records: int = 0
    stop_reason: str = ""

    @property
    def lost_bytes(self) -> int:
        """Bytes after the valid prefix (the cut chunk and anything after it)."""
        return self.src_bytes - self.valid_bytes


def repair_mcap(src: Path, dst: Path, *, overwrite: bool = False) -> RepairReport:
    """Read the valid prefix of `src` chunk by chunk and write it to `dst` as a complete, indexed MCAP.

    `dst` is written through a temporary file and replaced only when complete: a failed repair leaves an
    existing `dst` untouched. An existing `dst` (any file) is replaced only if `overwrite` (InputFileError
    otherwise, before `src` is read). Raises McapFormatError if `src` is not an MCAP file or `dst` is `src`
    (InputFileError if `dst` cannot be written)."""
    src, dst = Path(src), Path(dst)
    if same_file(dst, src):
        raise McapFormatError(f"dst: {dst} is the source {src} (the source is read while writing)")
    refuse_existing(dst, overwrite=overwrite, option="-o")
    state = ScanState()
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    topics: dict[int, str] = {}
    counts: dict[str, int] = {}
    messages = metadata = 0
    with atomic_path(dst, option="-o") as tmp, open(tmp, "wb") as out:
        writer = Writer(out, compression=CompressionType.ZSTD)
        writer.start(profile="", library="pmsm-hil mcap-repair")
        for record in scan_records(src, state):
            if isinstance(record, Schema):
                if record.id not in schema_ids:
                    schema_ids[record.id] = writer.register_schema(record.name, record.encoding, record.data)
            elif isinstance(record, Channel):
                if record.id not in channel_ids:
                    channel_ids[record.id] = writer.register_channel(
                        record.topic,
                        record.message_encoding,
                        schema_ids.get(record.schema_id, 0),
                        dict(record.metadata),
                    )
                    topics[record.id] = record.topic
            elif isinstance(record, Message):
                if record.channel_id not in channel_ids:
                    continue
                writer.add_message(
                    channel_ids[record.channel_id],
                    record.log_time,
                    record.data,
                    record.publish_time,
                    record.sequence,
                )
                messages += 1
                topic = topics[record.channel_id]
                counts[topic] = counts.get(topic, 0) + 1
            elif isinstance(record, Metadata):
                writer.add_metadata(record.name, dict(record.metadata))
                metadata += 1
        writer.finish()  # type: ignore[no-untyped-call]
    return RepairReport(
        src_bytes=state.file_bytes,
        valid_bytes=state.valid_bytes,
        source_complete=state.complete,
        chunks=state.chunks,
        messages=messages,
        messages_per_topic=counts,
        metadata_records=metadata,
        stop_reason=state.stop_reason,
    )

