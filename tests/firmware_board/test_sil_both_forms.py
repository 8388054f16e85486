"""A C firmware that sets both Command forms (duties and a switching sequence: tests/firmware_board/misbehave/
both_forms, from step 500 on) is reported by the target core as a duty Command with n_duties 0, and the host finds
it by rule `duty` (exit 4) at that step, in the native and the Python loop alike — before, the core sent the duties
and dropped the switching sequence silently."""

from __future__ import annotations

from pathlib import Path

import pytest

from pmsm_hil.hil.runner.contract import BOTH_FORMS_ON_WIRE, EndCode
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.sim_target.fw_build import build_firmware
from tests.firmware_board._runs import rated
from tests.firmware_board.conftest import need

BOTH = Path(__file__).with_name("misbehave") / "both_forms"


@pytest.fixture(scope="module")
def both_forms() -> Path:
    need("host")
    return build_firmware("host", BOTH).path


@pytest.mark.parametrize("loop", ["native", "python"])
def test_a_c_firmware_setting_both_forms_is_a_duty_finding(both_forms: Path, loop: str) -> None:
    m = run_closed_loop(rated(f"sil:{both_forms}", controller="external", settle_s=0.02, duration_s=0.05,
                              loop=loop)).metrics
    assert m["end_code"] == EndCode.DUT_VIOLATION, m["end_reason"]
    first = m["dut_violation_list"][0]
    assert first["rule"] == "duty" and first["detail"] == BOTH_FORMS_ON_WIRE, first
    assert first["period"] == 500 and "n_duties=0 (both forms)" in first["frame"], first
    assert m["dut_violations_by_rule"]["duty"] >= 1 and m["dut_violations_by_rule"]["missing"] == 0
