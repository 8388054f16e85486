"""`pytest --pyargs pmsm_hil.conformance --hil-target stm32g4:FW.elf` passes against the example STM32G474 firmware
(examples/stm32g4_foc) on the virtual board, every rule: its own FDCAN1 takes the Setpoints and ConfigParams and
sends ConfigAck, HeartbeatTarget and FaultTarget; while disabled its TIM1 outputs are off (MOE = 0), which the
board sends as the open bridge and the probe takes as the gates off."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.testing.pytest_session import ROOT, run_pytest
from tests.testing.test_conformance_suite import TEST_IDS


def test_the_example_firmware_conforms_on_the_virtual_board(tmp_path: Path) -> None:
    from pmsm_hil.sim_target.fw_build import build_firmware, missing_tools

    missing = missing_tools("stm32g474")
    if missing:
        pytest.skip(f"firmware board stm32g474: {', '.join(missing)} not installed")
    pytest.importorskip("unicorn", reason="the virtual STM32G4 board needs unicorn")
    elf = build_firmware("stm32g474").path
    s = run_pytest(["--pyargs", "pmsm_hil.conformance", "--hil-target", f"stm32g4:{elf}",
                    "--hil-board", str(ROOT / "examples" / "stm32g4_foc" / "board.toml"), "--hil-ts", "50e-6",
                    "--hil-controller", "external", "--hil-motor", "niu2020-ipmsm"], tmp_path, timeout_s=900.0)
    assert s.rc == 0, s.output[-5000:]
    assert set(s.cases) == TEST_IDS and not s.failed(), {n: s.cases[n].message for n in s.failed()}
