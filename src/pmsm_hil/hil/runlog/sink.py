"""`McapSink`: owns the MCAP writer in the logger process (channels, encoders, periodic flush, finish).

/periods and /frames are encoded by `pure_writer` (struct, no numpy) until those encoders have used
`PURE_CPU_S` of CPU time in the run, then by the numpy encoders (`cdr`, `encoding`), imported then: a short run
never pays numpy's import (≈ 0.15–0.2 CPU-s), a long one pays it once and then encodes at numpy's speed (≈ 3×
faster). /trace is always encoded by `pure_writer` on a little-endian host (as fast: mcap's `add_message` writes
it either way). Both write the same bytes. /link_faults, /target/console and /board/periods and the
message-by-message path (an mcap whose Writer `BulkMessages` cannot use) always use numpy."""

from __future__ import annotations

import contextlib
import json
import os
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, BinaryIO, Final

from mcap.well_known import MessageEncoding, SchemaEncoding

from pmsm_hil.dist_version import light_metadata

with light_metadata():  # mcap's writer asks its version at import: not importlib.metadata's ≈ 0.08 CPU-s for that
    from mcap.writer import CompressionType, Writer

from pmsm_hil.hil.runlog import layouts, pure_writer, topics
from pmsm_hil.hil.runlog.bulk_messages import BulkMessages
from pmsm_hil.hil.runlog.errors import RunLogError
from pmsm_hil.hil.runlog.salvage import end_after_last_record
from pmsm_hil.hil.runlog.topics import COMPRESSIONS

if TYPE_CHECKING:
    import numpy as np

    from pmsm_hil.hil.runlog.cdr import CdrMessage

#: mcap's compression of each name of `topics.COMPRESSIONS`
COMPRESSION_TYPES = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4, "none": CompressionType.NONE}
CHUNK_BYTES = 8 * 1024 * 1024
LIBRARY = "pmsm-hil runlog"
#: CPU time [s] the numpy-free encoders may use in a run before the numpy ones take over (numpy's import)
PURE_CPU_S: Final = 0.15


class McapSink:
    """Writes period, frame and trace blocks to an MCAP file (see docs/logging.md for the layout).

    `trace_fields`: the names of the trace's float64 fields. `pure_cpu_s` [s]: CPU time the numpy-free encoders
    may use before the numpy ones take over (0: numpy from the start)."""

    def __init__(self, path: Path, metadata: Mapping[str, str], compression: str = "lz4",
                 trace_fields: Sequence[str] = layouts.TRACE_FIELDS) -> None:
        if compression not in COMPRESSION_TYPES:
            raise RunLogError(f"compression: expected one of {sorted(COMPRESSIONS)}, got {compression!r}")
        self._path = Path(path)
        self._file: BinaryIO = open(path, "wb", buffering=1024 * 1024)  # noqa: SIM115 - closed in close()
        self._writer = Writer(self._file, chunk_size=CHUNK_BYTES, compression=COMPRESSION_TYPES[compression])
        self._writer.start(profile="", library=LIBRARY)
        w = self._writer
        json_enc = SchemaEncoding.JSONSchema
        self._ch_periods = w.register_channel(
            topics.TOPIC_PERIODS,
            MessageEncoding.CDR,
            w.register_schema(topics.SCHEMA_PERIODS, SchemaEncoding.ROS2, layouts.PERIOD_MSG.schema),
        )
        self._ch_frames = w.register_channel(
            topics.TOPIC_FRAMES,
            MessageEncoding.CDR,
            w.register_schema(topics.SCHEMA_FRAMES, SchemaEncoding.ROS2, layouts.FRAME_MSG.schema),
        )
        self._trace_fields = tuple(trace_fields)
        self._ch_trace = w.register_channel(
            topics.TOPIC_TRACE,
            MessageEncoding.CDR,
            w.register_schema(topics.SCHEMA_TRACE, SchemaEncoding.ROS2, layouts.ros2msg_schema(self._trace_fields)),
        )
        self._ch_faults = w.register_channel(
            topics.TOPIC_FAULTS,
            MessageEncoding.JSON,
            w.register_schema(topics.SCHEMA_FAULTS, json_enc, layouts.json_schema(layouts.FAULT_FIELDS, "link fault")),
        )
        self._ch_console = w.register_channel(
            topics.TOPIC_CONSOLE,
            MessageEncoding.JSON,
            w.register_schema(topics.SCHEMA_CONSOLE, json_enc, layouts.CONSOLE_JSON_SCHEMA),
        )
        self._ch_board = w.register_channel(
            topics.TOPIC_BOARD,
            MessageEncoding.JSON,
            w.register_schema(topics.SCHEMA_BOARD, json_enc, layouts.BOARD_JSON_SCHEMA),
        )
        ch_meta = w.register_channel(
            topics.TOPIC_METADATA,
            MessageEncoding.JSON,
            w.register_schema(topics.SCHEMA_METADATA, json_enc, layouts.METADATA_JSON_SCHEMA),
        )
        meta = dict(metadata)
        w.add_metadata(topics.TOPIC_METADATA, meta)
        w.add_message(ch_meta, 0, json.dumps(meta).encode(), 0)
        self.counts = {"periods": 0, "frames": 0, "trace_blocks": 0, "trace_samples": 0, "faults": 0, "console": 0,
                       "board": 0}
        self._bulk = BulkMessages.of(self._writer)
        self._closed = False
        self.pure_cpu_s = PURE_CPU_S
        self._pure_used_s = 0.0

    def _pure(self) -> bool:
        """Whether the next block goes through the numpy-free encoders."""
        return self._bulk is not None and pure_writer.LITTLE_ENDIAN and self._pure_used_s < self.pure_cpu_s

    def write_periods(self, raw: bytes) -> None:
        """Write one CDR message per period of the PERIOD_DTYPE block `raw`."""
        if self._pure():
            self._write_packed(raw, pure_writer.PERIODS, self._ch_periods, "periods")
            return
        from pmsm_hil.hil.records import PERIOD_DTYPE
        from pmsm_hil.hil.runlog import cdr

        self._write_fixed(raw, PERIOD_DTYPE, cdr.PERIOD_MSG, cdr.fill_periods, self._ch_periods, "periods")

    def write_frames(self, raw: bytes) -> None:
        """Write one CDR message per frame of the FRAME_DTYPE block `raw`."""
        if self._pure():
            self._write_packed(raw, pure_writer.FRAMES, self._ch_frames, "frames")
            return
        from pmsm_hil.hil.records import FRAME_DTYPE
        from pmsm_hil.hil.runlog import cdr

        self._write_fixed(raw, FRAME_DTYPE, cdr.FRAME_MSG, cdr.fill_frames, self._ch_frames, "frames")

    def _write_packed(self, raw: bytes, messages: pure_writer.FixedMessages, channel: int, count_key: str) -> None:
        """One fixed-size message per record of `raw`, encoded without numpy (`pure_writer`)."""
        if len(raw) % messages.record_bytes:
            raise RunLogError(f"{count_key}: block of {len(raw)} bytes is not whole {messages.record_bytes}-byte "
                              "records")
        if not raw:
            return
        assert self._bulk is not None
        start = time.process_time()
        records, times = messages.encode(raw, channel)
        self._bulk.add_packed(channel, records, messages.size, times)
        self.counts[count_key] += len(times)
        self._pure_used_s += time.process_time() - start

    def _write_fixed(self, raw: bytes, dtype: np.dtype, msg: CdrMessage,
                     fill: Callable[[np.ndarray, np.ndarray], None], channel: int, count_key: str) -> None:
        """One fixed-size message per record of the `dtype` block `raw` (payload by `fill`), stamped with its
        time, sequence = seq; the block's Message records are one numpy array."""
        import numpy as np

        from pmsm_hil.hil.runlog import encoding
        from pmsm_hil.hil.runlog.bulk_messages import message_records

        block = np.frombuffer(raw, dtype=dtype)
        n = block.shape[0]
        if n == 0:
            return
        records = message_records(msg.dtype, n)
        fill(records["data"], block)
        records["sequence"] = block["seq"]
        records["log_time"] = records["publish_time"] = encoding.periods_log_times_ns(block)
        if self._bulk is not None:
            self._bulk.add_records(channel, records)
        else:
            payloads = records.view(np.uint8).reshape(n, -1)[:, records.dtype.itemsize - msg.dtype.itemsize :]
            add = self._writer.add_message
            for rec, payload in zip(records.tolist(), payloads, strict=True):
                add(channel, rec[4], payload.tobytes(), rec[5], rec[3])
        self.counts[count_key] += n

    def write_faults(self, raw: bytes) -> None:
        """Write one message per injected link fault of the FAULT_DTYPE block `raw` on /link_faults."""
        from pmsm_hil.hil.records import FAULT_DTYPE
        from pmsm_hil.hil.runlog import encoding

        self._write_records(raw, FAULT_DTYPE, encoding.encode_faults, self._ch_faults, "faults")

    def write_board(self, raw: bytes) -> None:
        """Write one message per control period of the BOARD_DTYPE block `raw` on /board/periods."""
        from pmsm_hil.hil.runlog import board_records

        self._write_records(raw, board_records.BOARD_DTYPE, board_records.encode_board, self._ch_board, "board")

    def write_console(self, raw: bytes) -> None:
        """Write one message per target console line of the CONSOLE_DTYPE block `raw` on /target/console."""
        from pmsm_hil.hil.runlog import console

        self._write_records(raw, console.CONSOLE_DTYPE, console.encode_console, self._ch_console, "console")

    def _write_records(self, raw: bytes, dtype: np.dtype, encode: Callable[[np.ndarray], Sequence[bytes]],
                       channel: int, count_key: str) -> None:
        """One message per record of the `dtype` block `raw` (encoded by `encode`), stamped with its time,
        sequence = seq."""
        import numpy as np

        from pmsm_hil.hil.runlog import encoding

        block = np.frombuffer(raw, dtype=dtype)
        times = encoding.periods_log_times_ns(block).tolist()
        msgs, seqs = encode(block), block["seq"].tolist()
        if len(msgs) != len(times):
            raise RunLogError(f"{count_key}: {len(msgs)} messages encoded for {len(times)} records")
        if self._bulk is not None:
            self._bulk.add(channel, times, msgs, seqs)
        else:
            add = self._writer.add_message
            for t_ns, msg, seq in zip(times, msgs, seqs, strict=True):
                add(channel, t_ns, msg, t_ns, seq)
        self.counts[count_key] += block.shape[0]

    def write_trace(self, raw: bytes) -> None:
        """Write the trace block `raw` (the sink's trace fields, float64 each) as one CDR message stamped with its
        first sample time."""
        if not raw:
            return
        if len(raw) % (8 * len(self._trace_fields)):
            raise RunLogError(f"trace: block of {len(raw)} bytes is not whole samples of {len(self._trace_fields)} "
                              "float64")
        if pure_writer.LITTLE_ENDIAN:  # as fast as numpy's: the message is written by add_message either way
            t_ns, payload, n = pure_writer.trace_message(raw, len(self._trace_fields))
        else:
            import numpy as np

            from pmsm_hil.hil.records import trace_dtype
            from pmsm_hil.hil.runlog import encoding

            block = np.frombuffer(raw, dtype=trace_dtype(self._trace_fields))
            t_ns, payload, n = int(encoding.periods_log_times_ns(block[:1])[0]), encoding.encode_trace_cdr(block), \
                block.shape[0]
        self._writer.add_message(self._ch_trace, t_ns, payload, t_ns, self.counts["trace_blocks"])
        self.counts["trace_blocks"] += 1
        self.counts["trace_samples"] += n

    def flush(self) -> None:
        """End the current chunk, flush the file buffer and fsync: everything so far survives a kill."""
        self._writer.flush()  # type: ignore[no-untyped-call]
        os.fsync(self._file.fileno())

    def close(self) -> None:
        """Write the summary and footer, fsync and close the file (idempotent). A write that fails (a full
        disk) ends the file as `abandon` does and raises RunLogError saying what was kept."""
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.finish()  # type: ignore[no-untyped-call]
            self._file.flush()
            os.fsync(self._file.fileno())
        except OSError as exc:
            self._closed = False
            raise RunLogError(self.abandon(exc)) from None
        finally:
            with contextlib.suppress(OSError):
                self._file.close()

    def abandon(self, exc: OSError) -> str:
        """After a failed write (`exc`: a full disk, a file size limit): close the file without its summary and
        keep it as a valid MCAP file up to its last complete record, or remove it if not even its header fitted.
        Returns the cause and what became of the file, in words. Idempotent (later calls say nothing new)."""
        if self._closed:
            return f"cannot write {self._path}: {exc.strerror or exc}"
        self._closed = True
        with contextlib.suppress(OSError):  # the buffer that did not fit is dropped; the descriptor is closed
            self._file.close()
        cause = f"cannot write {self._path} ({exc.strerror or exc})"
        try:
            kept = end_after_last_record(self._path, self._ch_periods)
        except OSError as again:
            return (f"{cause}; the file ends at its last complete record (no MCAP footer: {again.strerror or again}"
                    f"; `hil mcap-repair` reads it)")
        if kept.bytes == 0:
            with contextlib.suppress(OSError):
                self._path.unlink()
            return f"{cause}; nothing of the log fitted: the file is removed"
        return (f"{cause}; the file is kept as a valid MCAP up to its last complete chunk: the first "
                f"{kept.messages} periods of the {self.counts['periods']} it received ({kept.bytes} bytes)")
