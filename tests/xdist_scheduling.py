"""How pytest-xdist shares this suite between its workers (`-n auto --dist loadfile`, pyproject.toml).

xdist's `loadfile` sends each test file whole to one worker (its module fixtures made once), in the order of
the number of tests per file. Here, in the same way, but:

- the units go out longest first (the measured seconds in COST_S; a unit not listed counts
  DEFAULT_TEST_S per test), so the minutes-long ones start at once on both workers instead of ending the
  session on one of them while the other is idle;
- files that share a costly session fixture go to one worker together (GROUPS), which then makes it once
  instead of once per worker.

Only the order and the grouping change: every test runs once, in a worker as before, with the same fixtures.
A figure in COST_S that no longer holds makes the schedule worse, never a test wrong. `--dist load`,
`loadscope`, ... on the command line get xdist's own schedulers."""

from __future__ import annotations

from collections import OrderedDict

import pytest
from xdist.remote import Producer
from xdist.scheduler import LoadScopeScheduling

#: files that share a costly session fixture -> the unit they run in (all on one worker)
GROUPS: dict[str, str] = {
    # inproc_session, spawn_session (tests/testing/conftest.py): pytest subprocess sessions
    "tests/testing/test_plugin.py": "tests/testing:pytest-sessions",
    "tests/testing/test_conformance_suite.py": "tests/testing:pytest-sessions",
    # live_run, second_run_dir (tests/dashboards/conftest.py): logged closed-loop runs, one streamed to Rerun
    **{f"tests/dashboards/{name}.py": "tests/dashboards:runs"
       for name in ("test_browser", "test_rrd", "test_report_and_cli", "test_report_whole_run")},
    # fan_fmus (tests/load_fmu/conftest.py): two FMUs compiled
    "tests/load_fmu/test_load_fmu.py": "tests/load_fmu:fan-fmus",
    "tests/load_fmu/test_containment.py": "tests/load_fmu:fan-fmus",
}

#: measured cost of a unit (its tests' setup + call + teardown) [s], from `--durations=0` at load ~10
COST_S: dict[str, float] = {}

#: cost of a test in a unit not in COST_S [s]
DEFAULT_TEST_S = 0.3


def scope_of(nodeid: str) -> str:
    """The unit a test belongs to: its file's group (GROUPS) or its file."""
    file = nodeid.split("::", 1)[0]
    return GROUPS.get(file, file)


class CostOrderedFileScheduling(LoadScopeScheduling):
    """xdist's loadfile with the units ordered by cost, grouped and split as the module says."""

    def __init__(self, config: pytest.Config, log: Producer | None = None) -> None:
        super().__init__(config, log if log is not None else Producer("costsched"))

    def _split_scope(self, nodeid: str) -> str:
        return scope_of(nodeid)

    def schedule(self) -> None:
        """xdist's LoadScopeScheduling.schedule, with the work queue ordered by cost (longest first)."""
        assert self.collection_is_completed
        if self.collection is not None:  # initial distribution done: more work to who needs it
            for node in self.nodes:
                self._reschedule(node)
            return
        if not self._check_nodes_have_same_collection():
            self.log("**Different tests collected, aborting run**")
            return
        self.collection = list(next(iter(self.registered_collections.values())))
        if not self.collection:
            return
        units: dict[str, dict[str, bool]] = {}
        for nodeid in self.collection:
            units.setdefault(self._split_scope(nodeid), {})[nodeid] = False

        def cost(item: tuple[str, dict[str, bool]]) -> float:
            scope, tests = item
            return COST_S.get(scope, DEFAULT_TEST_S * len(tests))

        self.workqueue = OrderedDict(sorted(units.items(), key=cost, reverse=True))
        for _ in range(max(0, len(self.nodes) - len(self.workqueue))):  # more workers than units
            unused, _assigned = self.assigned_work.popitem()
            unused.shutdown()
        for node in self.nodes:
            self._assign_work_unit(node)
        for node in self.nodes:  # each node starts with at least two units if possible
            self._reschedule(node)
        if not self.workqueue:
            for node in self.nodes:
                node.shutdown()
