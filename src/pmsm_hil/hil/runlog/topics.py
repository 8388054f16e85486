"""Topic names, schema names and the wire tags between the runner and the logger process."""

from __future__ import annotations

from typing import Final

TOPIC_PERIODS: Final = "/periods"
TOPIC_FRAMES: Final = "/frames"
TOPIC_TRACE: Final = "/trace"
TOPIC_FAULTS: Final = "/link_faults"
TOPIC_METADATA: Final = "/run/metadata"
TOPIC_CONSOLE: Final = "/target/console"
TOPIC_BOARD: Final = "/board/periods"

SCHEMA_PERIODS: Final = "pmsm_hil/msg/Period"  # ros2msg (CDR); "pmsm_hil.Period" (JSON) in older logs
SCHEMA_FRAMES: Final = "pmsm_hil/msg/Frame"  # ros2msg (CDR); "pmsm_hil.Frame" (JSON) in older logs
SCHEMA_TRACE: Final = "pmsm_hil/msg/TraceBlock"
SCHEMA_FAULTS: Final = "pmsm_hil.LinkFault"
SCHEMA_METADATA: Final = "pmsm_hil.RunMetadata"
SCHEMA_CONSOLE: Final = "pmsm_hil.ConsoleLine"
SCHEMA_BOARD: Final = "pmsm_hil.BoardPeriod"

# Notice kinds sent from the runner to the logger process (first byte of a notice).
KIND_PERIODS: Final = 1
KIND_FRAMES: Final = 2
KIND_TRACE: Final = 3
KIND_FAULTS: Final = 4
KIND_CONSOLE: Final = 5
KIND_BOARD: Final = 6
KIND_CLOSE: Final = 9

#: the chunk compressions a run log may be written with (`RunLogger(compression=...)`; mcap's types: sink.py)
COMPRESSIONS: Final = ("zstd", "lz4", "none")
