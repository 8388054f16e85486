"""The metrics registry is complete (every key a run produces is registered, and the reverse), docs/metrics.md
matches it, and the views read it."""

from __future__ import annotations

from typing import Any

import pytest

from pmsm_hil.app.cli.report_table import format_metrics
from pmsm_hil.app.compare.spread import SPREAD_METRICS
from pmsm_hil.app.compare.table import COLUMNS
from pmsm_hil.dashboards.report_html import TABLE
from pmsm_hil.hil.metrics.registry import (
    CLI,
    COMPARE,
    COMPARE_ROW,
    METRICS,
    REPORT,
    RUN,
    WINDOW,
    by_name,
    in_view,
    main,
    row_keys,
)
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario

#: keys produced only under conditions these short lockstep runs do not meet
#: sub-keys only some links have: SocketCAN's kernel drop counter (runs here use the virtual bus)
CONDITIONAL_SUBS = {("link", "kernel_dropped")}
CONDITIONAL = {"lateness_us", "lateness_histogram_us", "overruns", "overrun_threshold_us",  # real time only
               "realtime_sync_us", "cpu_dma_latency_us",  # real time only
               "exec_instructions", "mcu_clock_hz", "exec_time_model",  # qemu targets only (tests/firmware_board)
               # stm32g4 targets only (tests/board/test_link.py checks them)
               "board", "board_carrier_hz", "board_dead_time_ns", "board_isr_time_us", "board_cpu_load",
               "board_late_compares", "board_first_late_period", "board_handlers", "board_adc_sample_us",
               "board_setpoints_dropped", "board_configs_acked", "board_idle_periods", "board_break_trips",
               # stm32g4 targets running the firmware API over FDCAN1 (tests/firmware_board/test_template_stm32g4.py)
               "board_link", "board_can_bitrates", "board_turnaround_us", "board_turnaround_cycles",
               "board_late_replies", "board_missing_replies"}


def _metrics(motor: str, controller: str, load: float) -> dict[str, Any]:
    sc = load_scenario("steady").with_overrides(speed_rpm=1500.0, load_nm=load, settle_s=0.005, duration_s=0.01)
    return run_closed_loop(RunConfig(motor=load_motor(motor), scenario=sc, controller=controller)).metrics


@pytest.fixture(scope="module")
def runs() -> list[dict[str, Any]]:
    return [_metrics("niu2020-ipmsm", "fcs-mpc-1", 7.0), _metrics("zhang2021-dtpmsm", "mptc2", 40.0)]


def test_every_key_a_run_produces_is_registered_and_the_reverse(runs: list[dict[str, Any]]) -> None:
    registered = {m.key for m in METRICS if m.source in (WINDOW, RUN)}
    produced = set().union(*(set(m) for m in runs))
    assert produced - registered == set(), "metrics keys missing from src/pmsm_hil/hil/metrics/registry.py"
    assert registered - produced - CONDITIONAL == set(), "registered keys no run produced"
    for m in METRICS:  # sub-keys exist in their dicts (but those of one link kind)
        if m.sub is not None and m.key not in CONDITIONAL and (m.key, m.sub) not in CONDITIONAL_SUBS:
            assert m.sub in runs[0][m.key]


def test_docs_key_table_matches_the_registry() -> None:
    assert main(["--check"]) == 0


def test_names_are_unique_and_views_read_the_registry(runs: list[dict[str, Any]]) -> None:
    names = [m.name for m in METRICS]
    assert len(names) == len(set(names))
    assert by_name("exec_time_us.median").sub == "median"
    with pytest.raises(KeyError, match="not in the registry"):
        by_name("no_such_metric")
    assert [row[1] for row in TABLE] == [m.key for m in in_view(REPORT)]
    assert set(SPREAD_METRICS) == set(row_keys()) == {m.key for m in in_view(COMPARE_ROW)}
    assert set(row_keys(source=(COMPARE,))) <= set(COLUMNS)
    text = format_metrics(runs[0])
    for m in in_view(CLI):
        if m.sub is None and m.key in runs[0]:
            assert m.label in text


def test_format_of_a_cell() -> None:
    ripple = by_name("torque_ripple_rms_nm")
    assert ripple.format(0.12345) == "0.123" and ripple.format(None) == "n/a" and ripple.format(float("nan")) == "n/a"
    assert ripple.title == "torque ripple RMS [N·m]"
    assert by_name("end_reason").format("completed") == "completed"
