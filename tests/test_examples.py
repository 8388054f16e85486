"""The examples in examples/ run (short) and produce what they print."""

from __future__ import annotations

import runpy
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"


def test_plant_step_response_example(capsys: pytest.CaptureFixture[str]) -> None:
    module = runpy.run_path(str(EXAMPLES / "plant_step_response.py"))
    torques = module["main"](3)
    assert len(torques) == 3 and capsys.readouterr().out.count("torque =") == 3


def test_closed_loop_api_example(capsys: pytest.CaptureFixture[str]) -> None:
    module = runpy.run_path(str(EXAMPLES / "closed_loop_api.py"))
    results = module["main"](0.02)
    assert set(results) == {"mpcc", "dsvm-20"}
    assert all(abs(m["torque_mean_nm"] - 7.0) < 0.5 for m in results.values())
    assert "dsvm-20" in capsys.readouterr().out
