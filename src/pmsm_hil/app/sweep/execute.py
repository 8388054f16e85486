"""Runs a sweep's remaining runs on an engine into its results store, with progress; Ctrl-C keeps what
finished (the journal has it) and a later sweep on the same output directory resumes from there."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from pmsm_hil.app.sweep.configure import SweepRun, config_text
from pmsm_hil.app.sweep.engines import Engine
from pmsm_hil.app.sweep.progress import Progress
from pmsm_hil.app.sweep.store import LOST, ResultsStore
from pmsm_hil.app.sweep.task import RunTask, failed_row, run_task
from pmsm_hil.hil.runner.contract import EndCode


@dataclass(slots=True)
class SweepOutcome:
    """How the sweep went: runs in the plan, skipped as done before, run now, failed now, interrupted."""

    total: int
    skipped: int
    ran: int = 0
    failed: int = 0
    interrupted: bool = False
    #: the results files written at the end
    written: list[Path] = field(default_factory=list)


def tasks_for(runs: Sequence[SweepRun], store: Path | None) -> list[RunTask]:
    """The engine's tasks of these runs (logging into `store`/<run id> when given)."""
    where = None if store is None else str(Path(store).resolve())
    return [RunTask(r.run_id, r.cfg, r.columns(), config_text(r.point), where) for r in runs]


def run_sweep(runs: Sequence[SweepRun], engine: Engine, results: ResultsStore, *, mcap_store: Path | None = None,
              quiet: bool = False) -> SweepOutcome:
    """Run every run of `runs` whose id is not done in `results`; each row is journaled as it arrives, the
    results files rewritten now and then and at the end (also after Ctrl-C, which stops the engine's tasks
    and sets `interrupted`)."""
    order = [r.run_id for r in runs]
    done = results.done_ids()
    todo = [r for r in runs if r.run_id not in done]
    outcome = SweepOutcome(total=len(runs), skipped=len(runs) - len(todo))
    progress = Progress(len(runs), outcome.skipped, quiet=quiet)
    tasks = tasks_for(todo, mcap_store)
    progress.show()
    try:
        for i, row, error in engine.map_unordered(run_task, tasks):
            if error is not None:
                row = failed_row(tasks[i], int(EndCode.INTERNAL_ERROR), LOST + error)
            results.add(row)
            outcome.ran += 1
            failed = row.get("end_code") != int(EndCode.COMPLETED)
            outcome.failed += int(failed)
            progress.update(failed)
            results.maybe_write(order)
    except KeyboardInterrupt:
        outcome.interrupted = True
        engine.close(abort=True)
    finally:
        progress.show(final=True)
        outcome.written = results.write(order)
    return outcome


__all__ = ["SweepOutcome", "run_sweep", "tasks_for"]
