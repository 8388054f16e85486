"""The pytest plugin as a user gets it (a pytest subprocess with the installed entry point): examples/ci and a user
file pass under --hil-target inproc and spawn; a failing assertion names the signal and records a plot that
exists. In-process: how run choices become `hil run` arguments and errors, and a result's signals."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.runlog.reader import read_metadata
from pmsm_hil.testing import PLOT_PROPERTY, HilResult
from pmsm_hil.testing.plugin import HilSession, target_problem
from pmsm_hil.testing.runs import HilSettings, build_config, run_values
from tests.testing.pytest_session import ROOT, Session


def test_examples_ci_pass_in_process(inproc_session: tuple[Session, Path]) -> None:
    s, out = inproc_session
    examples = s.of("test_reference_firmware")
    assert len(examples) == 5 and not s.failed("test_reference_firmware"), s.output[-4000:]
    logs = sorted(out.glob("examples_ci_test_reference_firmware.py*/run-1/run.mcap"))
    assert len(logs) == 5 and all((p.parent / "metrics.json").is_file() for p in logs)


def test_a_user_file_runs_on_each_target(inproc_session: tuple[Session, Path], spawn_session: Session) -> None:
    for s in (inproc_session[0], spawn_session):
        assert s.outcomes("user_checks") == {"test_signals_cover_the_whole_run": "passed"}, s.output[-4000:]


def test_a_failing_assertion_names_the_signal_and_records_its_plot(inproc_session: tuple[Session, Path]) -> None:
    s, out = inproc_session
    case = s.cases["test_torque_is_flat"]
    assert s.rc == 1 and case.outcome == "failed", s.output[-4000:]
    assert "assert_is_constant: torque_nm not constant at 7 N·m ± 0.01" in case.message
    assert "during [0.01, 0.03] s: worst " in case.message and " at t = " in case.message
    plots = [Path(value) for name, value in case.properties if name == PLOT_PROPERTY]
    assert len(plots) == 1 and plots[0].is_file() and plots[0].read_bytes()[:4] == b"\x89PNG"
    assert plots[0].is_relative_to(out) and f"plot: {plots[0]}" in case.message
    assert f"[[ATTACHMENT|{plots[0]}]]" in s.output  # GitLab/Jenkins attachments from the captured output
    assert s.failed() == ["test_torque_is_flat"]  # the one failure of the session


def test_the_plugin_imports_cheaply() -> None:
    """Loaded by every pytest run: neither numpy nor the runner come with it."""
    code = ("import sys, pmsm_hil.testing as t; assert callable(t.hil) and callable(t.pytest_addoption); "
            "print(sorted(m for m in sys.modules if m.startswith(('numpy', 'pmsm_hil.hil', 'matplotlib'))))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_choices_become_run_option_values() -> None:
    """`hil.run`'s choices are run-option values (a dict, no command line), each with its source."""
    choices = {"speed": 1200, "load": -3.5, "params": {"lambda": 0.5}, "sets": {"j": 0.1}, "faults": "drop=0.01",
               "log_trace": True, "settle": None}
    values, sources = run_values(HilSettings(target="spawn", motor="zhang2021-dtpmsm", controller="mptc3"),
                                 Path("/o"), choices)
    assert values == {"target": "spawn", "link": "udp", "motor": "zhang2021-dtpmsm", "controller": "mptc3",
                      "out": Path("/o"), "speed": 1200, "load": -3.5, "param": {"lambda": 0.5}, "set": {"j": 0.1},
                      "fault": "drop=0.01", "log_trace": True}
    assert sources["load"] == "hil.run(load=...)" and sources["set"] == "hil.run(sets=...)"
    assert sources["motor"] == "--hil-motor" and sources["link"] == "--hil-target"
    values, _ = run_values(HilSettings(controller="foc"), None, {"controller": "mpcc", "lockstep_timeout": 5})
    assert values == {"target": "inproc", "link": "virtual", "no_log": True, "controller": "mpcc",
                      "lockstep_timeout": 5}
    # targets hil run has or will have: passed through as they are
    values, _ = run_values(HilSettings(target="external:socketcan:can0"), None, {})
    assert (values["target"], values["link"]) == ("external", "socketcan:can0")
    sil, _ = run_values(HilSettings(target="sil:fw.so"), None, {})
    assert sil["target"] == "sil:fw.so" and "link" not in sil  # hil run's own link and timeouts
    assert not {"step_timeout", "lockstep_timeout"} & set(sil)  # hil run's timeouts: host stalls do not count
    assert run_values(HilSettings(target="sil:fw.so"), None, {"step_timeout": 9})[0]["step_timeout"] == 9
    assert run_values(HilSettings(target="qemu:fw.elf"), None, {})[0]["target"] == "qemu:fw.elf"


def test_a_board_target_takes_its_board_and_period_from_the_session() -> None:
    """--hil-target stm32g4:FW.elf with --hil-board and --hil-ts: every run gets them unless it names its own."""
    from pmsm_hil.testing.plugin import target_problem

    settings = HilSettings(target="stm32g4:fw.elf", board="board.toml", ts=50e-6)
    values, sources = run_values(settings, None, {})
    assert (values["target"], values["board"], values["ts"]) == ("stm32g4:fw.elf", "board.toml", 50e-6)
    assert (sources["board"], sources["ts"]) == ("--hil-board", "--hil-ts")
    assert run_values(settings, None, {"ts": 1e-4})[0]["ts"] == 1e-4
    assert target_problem("stm32g4:missing.elf", Path("/nowhere")) == ("--hil-target stm32g4:missing.elf: "
                                                                       "/nowhere/missing.elf is not a file")
    assert target_problem("stm32g4:", Path("/")) == "--hil-target stm32g4:: stm32g4: needs the firmware's path " \
                                                    "(stm32g4:PATH)"


def test_bad_choices_fail_as_hil_run_does() -> None:
    with pytest.raises(ParameterError, match=r"hil.run\(speed=...\): --speed must be a number, got 'fast'"):
        build_config(HilSettings(), None, {"speed": "fast"})
    with pytest.raises(TypeError, match=r"unknown choice 'speedd' \(known: .*speed, step_timeout"):
        build_config(HilSettings(), None, {"speedd": 1})  # the run-option schema's keys, named
    with pytest.raises(ParameterError, match="unknown controller parameter 'nope'"):
        build_config(HilSettings(), None, {"params": {"nope": 1}})
    with pytest.raises(TypeError, match="'out' is set by the session"):
        build_config(HilSettings(), None, {"out": "x"})
    with pytest.raises(ValueError, match="external:LINKSPEC"):
        build_config(HilSettings(target="external"), None, {})
    cfg = build_config(HilSettings(motor="zhang2021-dtpmsm"), None, {"controller": "mptc3", "duration": 0.1})
    assert cfg.target == "inproc" and cfg.machine.phases == 6 and cfg.scenario.duration_s == 0.1


def test_a_result_reads_its_signals_from_the_log(tmp_path: Path) -> None:
    session = HilSession(HilSettings(), tmp_path)
    r = session.run("r", scenario="speed-step", settle=0.0, duration=0.03, speed=1200, controller="foc",
                    params={"speed_kp": 1.0}, sets={"j": 0.002})
    assert r.end_code == 0 and r.mcap_path == tmp_path / "r" / "run.mcap" and r.window == (0.0, 0.03)
    meta = read_metadata(r.mcap_path)
    assert meta["controller"] == "foc" and json.loads(meta["motor_set"]) == {"j": 0.002}
    assert json.loads(meta["controller_params"]) == {"speed_kp": 1.0}
    speed = r.signal("speed_rpm")
    assert speed.unit == "rpm" and len(speed) == 300 and speed.t[0] == 0.0
    assert speed.y[0] == pytest.approx(1000.0) and r.signal("speed_ref_rpm").y[0] == pytest.approx(1000.0)
    assert np.all(r.signal("exec_time_us").y[1:] > 0) and r.signal("exec_time_us").unit == "µs"
    assert np.isfinite(r.signal("torque_ref_nm").y[1:]).all()  # the in-process target reports it (from period 1)
    assert "vector_id" in r.signal_names and len(r.signal("vector_id")) == 300
    with pytest.raises(ValueError, match=r"unknown signal 'rpm' .*speed_rpm"):
        r.signal("rpm")
    again = HilResult.load(r.out_dir)
    assert again.window == r.window and again.metrics == r.metrics
    assert np.array_equal(again.signal("i_q").y, r.signal("i_q").y)


BAD_TARGETS = [
    ("qemux:fw.elf", "--hil-target 'qemux:fw.elf': not one of inproc, spawn, sil:PATH, qemu:PATH.elf"),
    ("sil:missing.so", "missing.so is not a file"),
    ("external", "--hil-target external needs a link: external:LINKSPEC"),
]


@pytest.mark.parametrize(("target", "expected"), BAD_TARGETS)
def test_a_bad_hil_target_is_named_in_one_line(tmp_path: Path, target: str, expected: str) -> None:
    """What the session's usage error says for each mistyped --hil-target (the test below: how a session ends)."""
    problem = target_problem(target, tmp_path)
    assert problem is not None and expected in problem and "\n" not in problem


def test_a_bad_hil_target_is_one_usage_error(tmp_path: Path) -> None:
    """A mistyped --hil-target stops the session at start-up with one line (pytest's usage error, exit 4) instead
    of failing every test that uses `hil` with a traceback (one pytest process: each mistyped kind's line is the
    test above's, raised by the same start-up hook)."""
    target, expected = BAD_TARGETS[0]
    (tmp_path / "test_user.py").write_text("def test_a(hil):\n    hil.run(duration=0.01)\n\n\n"
                                           "def test_b(hil):\n    hil.run(duration=0.01)\n")
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "--hil-target", target,
                           "test_user.py"], cwd=tmp_path, capture_output=True, text=True, timeout=300)
    out = (proc.stdout + proc.stderr).strip().splitlines()
    assert proc.returncode == pytest.ExitCode.USAGE_ERROR, out
    assert out == [f"ERROR: {out[0].removeprefix('ERROR: ')}"] and expected in out[0], out
    assert out[0] == f"ERROR: {target_problem(target, tmp_path)}"


def test_an_external_target_runs_without_xdist_workers() -> None:
    """`-n auto` (the repository's addopts) gives one board's tests no parallel workers; other targets keep xdist's
    count (None: the next implementation, xdist's own, decides)."""
    from types import SimpleNamespace

    from pmsm_hil.testing.plugin import pytest_xdist_auto_num_workers

    def config(target: str) -> pytest.Config:
        return SimpleNamespace(getoption=lambda name: {"--hil-target": target}[name])  # type: ignore[return-value]

    assert pytest_xdist_auto_num_workers(config("external:socketcan:can0")) == 0
    for target in ("inproc", "spawn", "sil:x.so", "qemu:x.elf"):
        assert pytest_xdist_auto_num_workers(config(target)) is None
