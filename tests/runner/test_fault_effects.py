"""The fault-effects table of docs/fault_effects.md comes from real runs: one short case per class."""

from __future__ import annotations

from pmsm_hil.app.bench.fault_effects import CASES, run_case


def test_cases_run_and_count_their_faults() -> None:
    clean = run_case("", controller="mpcc", duration_s=0.02)
    assert clean["link_faults"] is None and clean["dut_violations"] == 0
    dropped = run_case("drop=0.05", controller="mpcc", duration_s=0.02)
    assert dropped["link_faults"]["dropped"] > 0
    assert dropped["dut_violations_by_rule"]["missing"] > 0 and dropped["end_code"] == 0
    assert {label for label, _ in CASES} >= {"none", "drop 1 %", "dup 5 %", "silence 10 ms"}
