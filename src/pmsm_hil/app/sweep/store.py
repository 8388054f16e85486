"""The results of a sweep in its output directory, written as runs finish, resumable.

- `runs.jsonl`: the journal, one JSON row per finished run, appended and flushed to disk as each run
  finishes (a line cut by a crash is ignored when read back). It is the source of truth for resuming: a
  run id with a row there is done, unless it ended interrupted (end code 130) or its worker was lost.
- `results.json` (a list of rows), `results.parquet` (when pyarrow is installed) else `results.csv`: the
  rows of the current plan, in plan order, rewritten through a temporary file and renamed
  (src/pmsm_hil/hil/atomic_write.py) at most every `FLUSH_S` seconds during the sweep and at its end.
"""

from __future__ import annotations

import csv
import json
import os
import time
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, Final

from pmsm_hil.app.sweep.rows import normalize
from pmsm_hil.hil.atomic_write import atomic_path, write_text_atomic
from pmsm_hil.hil.errors import InputFileError
from pmsm_hil.hil.runner.contract import EndCode

JOURNAL: Final = "runs.jsonl"
RESULTS_JSON: Final = "results.json"
RESULTS_PARQUET: Final = "results.parquet"
RESULTS_CSV: Final = "results.csv"
#: every file a sweep writes in its output directory (--overwrite removes them)
SWEEP_FILES: Final = (JOURNAL, RESULTS_JSON, RESULTS_PARQUET, RESULTS_CSV, "report.html")
#: end_reason prefix of a row whose worker gave no answer (the run is retried on resume)
LOST: Final = "worker lost: "
#: least time between two rewrites of the results files during a sweep [s]
FLUSH_S: Final = 10.0


def has_parquet() -> bool:
    """True when pyarrow (Parquet) can be imported."""
    try:
        import pyarrow.parquet  # noqa: F401
    except ImportError:
        return False
    return True


def is_done(row: Mapping[str, Any]) -> bool:
    """A row that ends its run for good (resume skips it): not interrupted, not lost."""
    return row.get("end_code") != int(EndCode.INTERRUPTED) and not str(row.get("end_reason", "")).startswith(LOST)


class ResultsStore:
    """Rows by run id, read from the journal of an earlier sweep in `out` (unless `overwrite`)."""

    def __init__(self, out: Path, *, overwrite: bool = False) -> None:
        self.out = Path(out)
        if self.out.exists() and not self.out.is_dir():
            raise InputFileError(f"--out {self.out}: exists and is not a directory")
        try:
            self.out.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise InputFileError(f"--out {self.out}: cannot create the directory ({exc.strerror})") from None
        if overwrite:
            for name in SWEEP_FILES:
                (self.out / name).unlink(missing_ok=True)
        self.journal = self.out / JOURNAL
        self.rows: dict[str, dict[str, Any]] = {}
        self._read_journal()
        self._last_write = time.monotonic()

    def _read_journal(self) -> None:
        try:
            text = self.journal.read_text(encoding="utf-8")
        except FileNotFoundError:
            return
        except (OSError, UnicodeDecodeError) as exc:
            raise InputFileError(f"--out {self.out}: cannot read {JOURNAL} ({exc})") from None
        for line in text.splitlines():
            try:
                row = json.loads(line)
            except json.JSONDecodeError:
                continue  # a line cut by a crash or a kill
            if isinstance(row, dict) and isinstance(row.get("run_id"), str):
                self.rows[row["run_id"]] = row
        if text and not text.endswith("\n"):  # the next row starts on its own line
            with self.journal.open("a", encoding="utf-8") as fh:
                fh.write("\n")

    def done_ids(self) -> set[str]:
        """Run ids finished for good."""
        return {rid for rid, row in self.rows.items() if is_done(row)}

    def add(self, row: dict[str, Any]) -> None:
        """Append a finished run's row to the journal (flushed and synced) and keep it."""
        line = json.dumps(row, separators=(",", ":"), allow_nan=False, default=str) + "\n"
        self.rows[row["run_id"]] = row  # first: a Ctrl-C during the write still leaves it in the results files
        with self.journal.open("a", encoding="utf-8") as fh:
            fh.write(line)
            fh.flush()
            os.fsync(fh.fileno())

    def plan_rows(self, run_ids: Iterable[str]) -> list[dict[str, Any]]:
        """The rows of these run ids that exist, in that order."""
        return [self.rows[rid] for rid in run_ids if rid in self.rows]

    def maybe_write(self, run_ids: list[str]) -> None:
        """`write` if the last one is FLUSH_S seconds old."""
        if time.monotonic() - self._last_write >= FLUSH_S:
            self.write(run_ids)

    def write(self, run_ids: list[str]) -> list[Path]:
        """Rewrite results.json and results.parquet (or .csv) with the plan's rows; the paths written."""
        rows = self.plan_rows(run_ids)
        self._last_write = time.monotonic()
        written = [self.out / RESULTS_JSON]
        write_text_atomic(written[0], json.dumps(rows, indent=1, allow_nan=False, default=str) + "\n",
                          option="--out")
        cols, table = normalize(rows)
        if has_parquet():
            written.append(self.out / RESULTS_PARQUET)
            _write_parquet(written[-1], cols, table)
        else:
            written.append(self.out / RESULTS_CSV)
            _write_csv(written[-1], cols, table)
        return written


def _write_parquet(path: Path, cols: list[str], rows: list[dict[str, Any]]) -> None:
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.table({c: [r[c] for r in rows] for c in cols}) if rows else pa.table({})
    with atomic_path(path, option="--out") as tmp:
        pq.write_table(table, tmp)


def _write_csv(path: Path, cols: list[str], rows: list[dict[str, Any]]) -> None:
    with atomic_path(path, option="--out") as tmp, tmp.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh)
        writer.writerow(cols)
        for r in rows:
            writer.writerow(["" if r[c] is None else r[c] for c in cols])


def read_results(out: Path) -> list[dict[str, Any]]:
    """The rows of results.json in `out`."""
    path = Path(out) / RESULTS_JSON
    try:
        rows = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError) as exc:
        raise InputFileError(f"{path}: cannot read the sweep results ({exc})") from None
    if not isinstance(rows, list):
        raise InputFileError(f"{path}: not a list of rows")
    return rows


__all__ = ["JOURNAL", "LOST", "RESULTS_CSV", "RESULTS_JSON", "RESULTS_PARQUET", "SWEEP_FILES", "ResultsStore",
           "has_parquet", "is_done", "read_results"]
