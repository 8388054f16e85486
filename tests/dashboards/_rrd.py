"""Read an .rrd back with the Rerun SDK: rows per entity of the recording (static rows excluded)."""

from __future__ import annotations

from pathlib import Path


def rows_per_entity(path: Path) -> dict[str, int]:
    from rerun.chunk import RrdReader

    reader = RrdReader(path)
    counts: dict[str, int] = {}
    for chunk in reader.stream(store=reader.recordings()[0]):
        if chunk.is_static:
            continue
        counts[chunk.entity_path] = counts.get(chunk.entity_path, 0) + chunk.num_rows
    return counts
