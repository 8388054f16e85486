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
    "tests/load_fmu/test_replay_fmu_load.py": "tests/load_fmu:fan-fmus",
}

#: measured cost of a unit (the sum of its tests' setup, call and teardown durations) [s]: `--durations=0` of
#: whole-suite runs with two workers at load 10-25 (2026-11-28; only the order matters)
COST_S: dict[str, float] = {
    "tests/firmware_board/test_sil_isolation.py": 462,
    "tests/bench/test_labgrid_places.py": 150,
    "tests/firmware/test_c_unit.py": 356,
    "tests/runner/test_dut_contract.py": 233,  # 353 before the forked loggers (h-suite9a: wall × 0.66)
    "tests/load_fmu:fan-fmus": 190,  # 316 before the FMUs cached by content and the sweep's figure (h-suite10e)
    "tests/runner/test_operating_range.py": 232,  # 263 before the flux-map fit cached (h-suite10c: wall × 0.88)
    "tests/runner/test_wire_serial.py": 246,
    "tests/runner/test_machine_matrix.py": 235,
    "tests/testing:pytest-sessions": 220,
    "tests/firmware_board/test_fw_build_ux.py": 209,
    "tests/dashboards:runs": 155,  # 175 before the served viewer's test waited on its state (h-suite10a)
    "tests/compare/test_compare_report.py": 160,
    "tests/runner/test_link_auth_runs.py": 145,
    "tests/runner/test_bench_realtime.py": 141,
    "tests/plant/test_pwm_duty.py": 131,
    "tests/runner/test_interrupt_log.py": 100,  # 130 before the hil zygote (h-suite10c: wall × 0.77)
    "tests/firmware_board/test_qemu.py": 80,  # 124 before its QEMU runs were shortened (h-suite10b: CPU × 0.6)
    "tests/firmware_board/test_host_stall.py": 60,  # five 3-s stops, each beside a calm run (h-suite10b, load 10-18)
    "tests/runner/test_wire_spin.py": 118,
    "tests/dashboards/test_live_viewer.py": 116,
    "tests/firmware/test_fcs_readings_closed_loop.py": 116,
    "tests/runner/test_loop.py": 113,
    "tests/runner/test_wire_socketcan.py": 110,
    "tests/runner/test_spawn_safety.py": 102,
    "tests/firmware_board/test_template_stm32g4.py": 150,  # 7 board/sil/qemu runs (≈ 220 s at load ≈ 10)
    "tests/firmware_board/test_qemu_endings.py": 91,
    "tests/firmware_board/test_template_cpp.py": 89,
    "tests/runlog/test_full_disk.py": 83,
    "tests/runner/test_small_ts.py": 79,
    "tests/runner/test_run_dir_lock.py": 50,  # 74 before the hil zygote (h-suite10c)
    "tests/runner/test_wire_udp.py": 72,
    "tests/runner/test_callback_link.py": 68,
    "tests/sweep/test_outputs.py": 66,
    "tests/firmware_board/test_template.py": 64,
    "tests/test_layers.py": 62,
    "tests/plant/test_fluxmap.py": 62,
    "tests/runner/test_replay_run.py": 33,  # 22 short logged runs replayed: 60 before the forked loggers
    "tests/runner/test_links_and_modes.py": 59,
    "tests/runlog/test_durability.py": 32,  # 54 before the shorter finalise run (h-suite10e)
    "tests/runner/test_cli_inputs_outputs.py": 19,  # 46 before the forked loggers
    "tests/sweep/test_engines.py": 40,  # 45 before Ray's workers inherited the BLAS environment
    "tests/sweep/test_compare_engines.py": 43,
    "tests/compare/test_compare.py": 43,
    "tests/firmware/test_bench_controllers.py": 42,
    "tests/firmware_board/test_sil.py": 41,
    "tests/sweep/test_resume.py": 40,
    "tests/protocol/test_codec.py": 35,
    "tests/runner/test_shared_bus.py": 35,
    "tests/plant/test_strict_c.py": 5,  # 31 before the verdicts kept by content (h-suite10e)
    "tests/runlog/test_repair.py": 30,
    "tests/runner/test_safe_stop.py": 30,
    "tests/runlog/test_benchmark.py": 29,
    "tests/runner/test_pm_qos.py": 28,
    "tests/protocol/test_c_codec.py": 25,
    "tests/runlog/test_bulk_messages.py": 25,
    "tests/runlog/test_roundtrip.py": 25,
    "tests/plant/test_accuracy.py": 24,
    "tests/runner/test_new_machine_kind.py": 3,  # 22 while its kernel was compiled in every session
    "tests/protocol/test_link_faults.py": 20,
    "tests/runner/test_bench_adapters.py": 20,
    "tests/runner/test_bench_memory.py": 20,
    "tests/firmware/test_dsvm_family_closed_loop.py": 20,
    "tests/runlog/test_can_log.py": 19,
    "tests/protocol/test_decoder_stats.py": 16,
    "tests/metrics/test_streaming.py": 15,
    "tests/runner/test_run_cli.py": 14,
    "tests/runner/test_target_restart.py": 14,
    "tests/protocol/test_cobs.py": 13,
    "tests/test_examples.py": 12,
    "tests/protocol/test_bench_cli.py": 12,
    "tests/runner/test_closed_loop.py": 11,
    "tests/plant/test_replay_cli.py": 10,
    "tests/runner/test_adc_delay.py": 10,
    "tests/runner/test_logger_fork_server.py": 12,  # a runner killed with a forked logger open (2026-11-29, load 10)
    "tests/runner/test_run_options.py": 10,
}

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
