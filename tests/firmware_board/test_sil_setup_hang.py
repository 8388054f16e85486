"""A SIL firmware that never returns from `hil_app_init` or `hil_app_config`: "target hung in
hil_app_init" / "target hung in hil_app_config", exit 3, within a few --step-timeout of its own CPU time,
metrics.json written, the process killed. A firmware whose hil_app_init returns keeps its crash in hil_app_config
named as before (test_sil_isolation.py)."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pmsm_hil.sim_target.fw_build import build_firmware
from tests.firmware_board.conftest import ROOT, need

MISBEHAVE = Path(__file__).with_name("misbehave")


@pytest.fixture(scope="module")
def firmware() -> dict[str, Path]:
    need("host")
    return {kind: build_firmware("host", MISBEHAVE / kind).path for kind in ("init_hang", "config_hang")}


@pytest.mark.parametrize("where", ["init", "config"])
def test_a_hang_in_set_up_is_named_exit_3(firmware: dict[str, Path], tmp_path: Path, where: str) -> None:
    out = tmp_path / "run"
    t0 = time.monotonic()
    proc = subprocess.run([sys.executable, "-m", "pmsm_hil.app.cli.main", "run",
                           f"--target=sil:{firmware[f'{where}_hang']}", "--controller=external", "--settle=0.01",
                           "--duration=0.01", f"--out={out}", "--step-timeout=0.5"],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    elapsed = time.monotonic() - t0
    assert proc.returncode == 3, proc.stderr[-2000:]
    assert f"target hung in hil_app_{where}: it computed for --step-timeout 0.5 s" in proc.stderr
    assert elapsed < 30.0  # the interpreter's start-up on a loaded machine included; the hang itself: ~0.5 s CPU
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["end_code"] == 3 and metrics["end_period"] == -1
    assert metrics["end_reason"].startswith(f"target hung in hil_app_{where}")
