"""The setpoint verdict: `setpoint_held` and `setpoint_error` in metrics.json, the summary's
line, `hil run --expect-hold` → exit 5, `--hold-tolerance` / the scenario's `hold_tolerance_pct`, and the pytest
API's check."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.runner.scenario import DEFAULT_HOLD_TOLERANCE_PCT, Scenario
from pmsm_hil.testing.runs import HilSettings, SetpointNotHeldError, execute

#: a short steady run at 1500 rpm; vdc = 150 V cannot reach it (the voltage limit)
SHORT = ["--settle", "0.1", "--duration", "0.1"]


def _metrics(out: Path) -> dict:
    return json.loads((out / "metrics.json").read_text(encoding="utf-8"))


def test_the_default_run_holds_its_setpoint(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", *SHORT, "--out", str(tmp_path / "r"), "--expect-hold"]) == 0
    m = _metrics(tmp_path / "r")
    assert m["setpoint_held"] is True and m["setpoint_mode"] == "speed"
    assert m["hold_tolerance_pct"] == DEFAULT_HOLD_TOLERANCE_PCT
    assert abs(m["setpoint_error"]["relative_pct"]) <= DEFAULT_HOLD_TOLERANCE_PCT
    lines = capsys.readouterr().out.splitlines()
    assert any(ln.strip().startswith("setpoint held: yes") for ln in lines[:8])


def test_a_missed_setpoint_is_reported_and_expect_hold_exits_5(tmp_path: Path,
                                                               capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "vdc150"
    assert main(["run", *SHORT, "--set", "vdc=150", "--speed", "1500", "--out", str(out), "--expect-hold"]) == 5
    m = _metrics(out)
    assert m["setpoint_held"] is False and m["end_code"] == 5
    assert m["setpoint_error"]["absolute"] < 0 and m["setpoint_error"]["relative_pct"] < -DEFAULT_HOLD_TOLERANCE_PCT
    captured = capsys.readouterr()
    assert any(ln.strip().startswith("setpoint held: NO") for ln in captured.out.splitlines()[:8])
    assert "exit 5" in captured.err
    # without --expect-hold the same run completes (exit 0) and still says so
    assert main(["run", *SHORT, "--set", "vdc=150", "--no-log", "--json", str(tmp_path / "m.json")]) == 0
    assert json.loads((tmp_path / "m.json").read_text())["setpoint_held"] is False
    # a wide enough tolerance holds it
    err = abs(m["setpoint_error"]["relative_pct"])
    assert main(["run", *SHORT, "--set", "vdc=150", "--no-log", "--expect-hold", "--hold-tolerance",
                 f"{err + 1.0:g}"]) == 0


def test_the_tolerance_is_a_scenario_key_checked_like_the_others() -> None:
    assert Scenario("s", hold_tolerance_pct=7.5).hold_tolerance_pct == 7.5
    with pytest.raises(ParameterError, match="hold_tolerance_pct"):
        Scenario("s", hold_tolerance_pct=0.0)


def test_the_pytest_api_asserts_the_setpoint_unless_told_not_to(tmp_path: Path) -> None:
    choices = {"settle": 0.1, "duration": 0.1, "sets": {"vdc": 150}}
    with pytest.raises(SetpointNotHeldError, match="setpoint not held"):
        execute(HilSettings(), tmp_path / "a", choices)
    r = execute(HilSettings(), tmp_path / "b", {**choices, "expect_hold": False})
    assert r.end_code == 0 and r.metrics["setpoint_held"] is False
