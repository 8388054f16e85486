"""Pruning of the suite's own per-user caches (tests/plant/compile_cache.py, tests/load_fmu/fan_fmu.py)."""

from __future__ import annotations

import time
from pathlib import Path

#: entries not used for this long are removed when a new one is stored [s]
STALE_S = 14 * 24 * 3600.0


def remove_stale(folder: Path, pattern: str) -> None:
    """Remove the files of `folder` matching `pattern` not used (modified or touched) for STALE_S."""
    now = time.time()
    for old in folder.glob(pattern):
        try:
            if now - old.stat().st_mtime > STALE_S:
                old.unlink()
        except OSError:
            pass
