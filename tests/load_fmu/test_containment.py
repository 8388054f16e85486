"""The load FMU in its own process: an FMU that crashes (SIGSEGV, abort, stack overflow),
exits (`_exit(0)`), loops forever or blocks ends the run with exit 3 naming the cause, the call and the period;
metrics.json is written, the MCAP holds end_period + 1 periods and the safe stop is confirmed. Ctrl-C ends an
endless-looping FMU's run; a pytest session survives a crashing FMU; absurd torques and out-of-range integer
settings are one-line endings / errors; `--load-fmu-isolation none` is the explicit in-process mode."""

from __future__ import annotations

import json
import multiprocessing.util
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.errors import HilError
from pmsm_hil.hil.load_fmu.spec import load_fmu_spec
from pmsm_hil.hil.runlog.reader import read_periods
from pmsm_hil.hil.runner.run import run_closed_loop
from tests.load_fmu.fan_fmu import build_fan_fmu, have_gcc
from tests.load_fmu.test_load_fmu import _cli_config, _config
from tests.testing.pytest_session import ROOT, run_pytest

pytestmark = pytest.mark.skipif(not have_gcc(), reason="gcc builds the test FMUs")

#: the misbehaving FMUs misbehave from t = 10 ms: period 100 at Ts = 100 µs
FAIL_AT_S, FAIL_PERIOD = 0.01, 100
RUN = ["--load-fmu-set", f"fail_at={FAIL_AT_S}", "--speed", "1000", "--settle", "0.02", "--duration", "0.03"]


@pytest.fixture(scope="module")
def bad_fmus(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A fan FMU per misbehaviour (tests/load_fmu/fan_fmu.py BAD), FMI 2; `init-segv` / `init-abort` /
    `init-loop`: SIGSEGV / abort() / an endless loop in fmi2ExitInitializationMode; `fmi3-segv`: SIGSEGV in
    fmi3DoStep."""
    out = tmp_path_factory.mktemp("bad-fmu")
    fmus = {bad: build_fan_fmu(out / bad, 2, bad=bad) for bad in ("segv", "abort", "stack", "exit0", "loop",
                                                                    "block", "huge")}
    fmus["init-segv"] = build_fan_fmu(out / "init-segv", 2, bad="segv", bad_in_init=True)
    fmus["fmi3-segv"] = build_fan_fmu(out / "fmi3-segv", 3, bad="segv")
    fmus["init-loop"] = build_fan_fmu(out / "init-loop", 2, bad="loop", bad_in_init=True)
    fmus["init-abort"] = build_fan_fmu(out / "init-abort", 2, bad="abort", bad_in_init=True)
    return fmus


def _outputs(out: Path) -> tuple[dict[str, Any], np.ndarray]:
    return json.loads((out / "metrics.json").read_text(encoding="utf-8")), read_periods(out / "run.mcap")


@pytest.mark.parametrize(("bad", "cause"), [
    ("segv", "crashed (SIGSEGV in fmi2DoStep at period 100)"),
    ("abort", "crashed (SIGABRT in fmi2DoStep at period 100)"),
    ("stack", "crashed (SIGSEGV in fmi2DoStep at period 100)"),
    ("exit0", "crashed (exit code 0 in fmi2DoStep at period 100)"),
    ("fmi3-segv", "crashed (SIGSEGV in fmi3DoStep at period 100)"),
    ("loop", "hung: fmi2DoStep at period 100 did not return within --step-timeout 0.2 s"),
    ("block", "hung: fmi2DoStep at period 100 did not return within --step-timeout 0.2 s"),
])
def test_a_misbehaving_fmu_ends_the_run_with_exit_3(bad_fmus: dict[str, Path], bad: str, cause: str, tmp_path: Path,
                                                    fmu_temp: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`hil run` (in this process: the FMU's crash must not take it) returns 3, names the cause, writes
    metrics.json and an MCAP of end_period + 1 periods (every period before the FMU's), safe stop confirmed."""
    out = tmp_path / "run"
    # a crash is not a hang at any load: 30 s to crash (the stack overflow's recursion took > 0.2 s of wall time at
    # load 14 and was named a hang); the hangs' 0.2 s is their cause's
    timeout = "0.2" if cause.startswith("hung") else "30"
    assert main(["run", "--load-fmu", str(bad_fmus[bad]), *RUN, "--step-timeout", timeout, "--out", str(out)]) == 3
    assert _fmu_temp_dirs(fmu_temp) == set() and _serving(os.getpid()) == []  # folder removed, process gone
    metrics, periods = _outputs(out)
    assert metrics["end_code"] == 3 and cause in metrics["end_reason"], metrics["end_reason"]
    assert "\n" not in metrics["end_reason"] and metrics["safe_state"] is True
    assert metrics["safe_stop_confirmed"] is True
    assert len(periods) == metrics["end_period"] + 1 == FAIL_PERIOD
    assert metrics["load_fmu"]["steps"] == FAIL_PERIOD
    err = capsys.readouterr().err
    assert f"hil: run ended (exit 3): load FMU 'FanLoad' ({bad_fmus[bad]}) {cause}" in err


@pytest.mark.parametrize(("bad", "timeout", "cause"), [
    ("init-segv", "30", "crashed (SIGSEGV in fmi2ExitInitializationMode while initialising)"),
    ("init-abort", "30", "crashed (SIGABRT in fmi2ExitInitializationMode while initialising)"),
    ("init-loop", "2", "hung: fmi2ExitInitializationMode while initialising did not return within --step-timeout 2 s"),
])
def test_a_crash_in_initialisation_is_a_safety_stop_with_outputs(bad_fmus: dict[str, Path], bad: str, timeout: str,
                                                                 cause: str, tmp_path: Path, fmu_temp: Path,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """A crash or hang in fmi2ExitInitializationMode (before the first period: nothing enabled yet) is a safety
    stop like one in a doStep: exit 3, one line naming the cause and the call, metrics.json and a readable MCAP
    of 0 periods, the disabling Setpoint sent and confirmed, no temp folder or FMU process left behind."""
    out = tmp_path / "run"
    # the step timeout also bounds each set-up call (dlopen included): generous but for the endless loop
    assert main(["run", "--load-fmu", str(bad_fmus[bad]), "--step-timeout", timeout, "--settle", "0", "--duration",
                 "0.01", "--out", str(out)]) == 3
    assert _fmu_temp_dirs(fmu_temp) == set() and _serving(os.getpid()) == []
    metrics, periods = _outputs(out)
    line = metrics["end_reason"]
    assert metrics["end_code"] == 3 and line.startswith(f"load FMU 'FanLoad' ({bad_fmus[bad]}) {cause}")
    assert line.endswith("; the run did not start, target disabled") and "\n" not in line
    assert metrics["total_periods"] == 0 and metrics["end_period"] == -1 and len(periods) == 0
    assert metrics["target_disabled"] is True and metrics["safe_stop_confirmed"] is True
    assert metrics["load_fmu"]["model_name"] == "FanLoad" and metrics["load_fmu"]["steps"] == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert f"hil: run ended (exit 3): {line}; partial log: {out / 'run.mcap'}" in err, err


def _serving(parent_pid: int) -> list[int]:
    """Pids of live load FMU processes of the run `parent_pid` (Linux /proc)."""
    pids = []
    for cmdline in Path("/proc").glob("[0-9]*/cmdline"):
        try:
            argv = cmdline.read_bytes().split(b"\0")
        except OSError:
            continue
        if b"pmsm_hil.hil.load_fmu.serve" in argv and argv[-2:] == [str(parent_pid).encode(), b""]:
            pids.append(int(cmdline.parent.name))
    return pids


@pytest.fixture
def fmu_temp(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The folder this test's load FMUs are unzipped into (tempfile's, for this test only: another xdist worker's
    FMU folders in the shared TMPDIR are not this run's)."""
    folder = tmp_path / "tmp"
    folder.mkdir()
    # multiprocessing's own folder (its AF_UNIX sockets: the logger's and the sweeps' fork servers) is made once per
    # process, at its first use: made now, in the usual TMPDIR, not below this test's (too long for a socket address)
    multiprocessing.util.get_temp_dir()
    monkeypatch.setattr(tempfile, "tempdir", str(folder))
    return folder


def _fmu_temp_dirs(folder: Path) -> set[Path]:
    return set(folder.glob("hil-load-fmu-*"))


def _hil_run(args: list[str], **kw: Any) -> subprocess.Popen[str]:
    return subprocess.Popen([sys.executable, "-m", "pmsm_hil.app.cli.main", "run", *args], cwd=ROOT, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, **kw)


def _interrupt_in_endless_loop(fmu: Path, tmp_path: Path, signum: int) -> tuple[float, int, str, Path, int]:
    """`hil run` (a subprocess) with an FMU looping for good in fmi2DoStep and a step timeout of 100 s: once the
    FMU loops (its marker file), `signum`; (seconds to the exit, exit status, stderr, --out, its pid)."""
    marker, out = tmp_path / "looping", tmp_path / "run"
    proc = _hil_run(["--load-fmu", str(fmu), *RUN, "--step-timeout", "100", "--out", str(out)],
                    env={**os.environ, "FAN_MARKER": str(marker)})
    try:
        deadline = time.monotonic() + 120.0
        while not marker.exists():
            assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()
            time.sleep(0.01)
        time.sleep(0.1)
        t0 = time.monotonic()
        proc.send_signal(signum)
        _, err = proc.communicate(timeout=60)
        return time.monotonic() - t0, proc.returncode, err, out, proc.pid
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_ends_an_endless_looping_fmu(bad_fmus: dict[str, Path], tmp_path: Path, signum: int) -> None:
    """Ctrl-C / SIGTERM while the FMU loops for good: the run ends as interrupted (130) with its outputs, long
    before the 100 s step timeout; the FMU's process is gone (the 1 s figure: the `timing` test below)."""
    seconds, rc, err, out, pid = _interrupt_in_endless_loop(bad_fmus["loop"], tmp_path, signum)
    assert rc == 130, err
    assert seconds < 30.0
    metrics, periods = _outputs(out)
    assert metrics["end_code"] == 130 and len(periods) == metrics["end_period"] + 1 == FAIL_PERIOD
    assert _serving(pid) == []


def test_ctrl_c_ends_an_fmu_looping_in_its_initialisation(bad_fmus: dict[str, Path], tmp_path: Path) -> None:
    """An endless loop in fmi2ExitInitializationMode (before the run): Ctrl-C ends `hil run` (130, "before the run
    started") long before the 100 s step timeout with metrics.json and an MCAP of 0 periods, the target disabled,
    the FMU's process gone."""
    seconds, rc, err, out, pid = _interrupt_in_endless_loop(bad_fmus["init-loop"], tmp_path, signal.SIGINT)
    assert rc == 130 and "interrupted" in err and "before the run started" in err, err
    assert seconds < 30.0 and _serving(pid) == []
    metrics, periods = _outputs(out)
    assert metrics["end_code"] == 130 and metrics["total_periods"] == 0 and len(periods) == 0
    assert metrics["target_disabled"] is True


@pytest.mark.timing
def test_ctrl_c_ends_an_endless_looping_fmu_within_1_s(bad_fmus: dict[str, Path], tmp_path: Path) -> None:
    seconds, rc, err, _, _ = _interrupt_in_endless_loop(bad_fmus["loop"], tmp_path, signal.SIGINT)
    assert rc == 130 and seconds < 1.0, (seconds, err)


def test_an_absurd_torque_ends_the_run_in_one_line_with_metrics(bad_fmus: dict[str, Path], tmp_path: Path) -> None:
    """1e30 N·m from the FMU: beyond the ±1e6 N·m bound, the run ends at that period (no metric sees it)."""
    out = tmp_path / "run"
    assert main(["run", "--load-fmu", str(bad_fmus["huge"]), *RUN, "--out", str(out)]) == 1
    metrics, periods = _outputs(out)
    reason = metrics["end_reason"]
    assert "torque output 1e+30 N*m beyond the bound +-1e+06 N*m" in reason and "\n" not in reason
    assert len(periods) == metrics["end_period"] + 1 == FAIL_PERIOD + 1
    assert float(np.max(np.abs(periods["load_torque"]))) < 1.0


def test_a_pytest_session_survives_a_crashing_fmu(bad_fmus: dict[str, Path], fan_fmus: dict[int, Path],
                                                  tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("LOAD_FMU_OK", str(fan_fmus[2]))
    monkeypatch.setenv("LOAD_FMU_BAD", str(bad_fmus["segv"]))
    s = run_pytest([str(Path(__file__).with_name("misbehave") / "fmu_session_checks.py")], tmp_path)
    assert s.outcomes("fmu_session_checks") == {"test_before_the_crash": "passed", "test_the_crash": "passed",
                                                "test_after_the_crash": "passed"}, s.output[-4000:]
    assert s.rc == 0


def _with_integer(xml: str) -> str:
    """The fan's model description with an Integer parameter `n` (FMI 2)."""
    var = ('<ScalarVariable name="n" valueReference="7" causality="parameter" variability="fixed" '
           'initial="exact"><Integer start="1"/></ScalarVariable>\n  </ModelVariables>')
    return xml.replace("</ModelVariables>", var)


@pytest.mark.parametrize(("value", "expected"), [
    ("1e308", "--load-fmu-set n: an Integer parameter (int32: -2147483648 to 2147483647), got 1e+308"),
    ("2147483648", "--load-fmu-set n: an Integer parameter (int32: -2147483648 to 2147483647), got 2.14748e+09"),
    ("1.5", "--load-fmu-set n: an Integer parameter (int32"),
])
def test_integer_settings_are_range_checked(tmp_path: Path, value: str, expected: str) -> None:
    fmu = build_fan_fmu(tmp_path, 2, name="with_n", xml=_with_integer)
    with pytest.raises(HilError) as info:
        _cli_config(["--load-fmu", str(fmu), "--load-fmu-set", f"n={value}"])
    assert expected in str(info.value) and "\n" not in str(info.value)


def test_boolean_settings_take_0_1_true_false(tmp_path: Path) -> None:
    fmu = build_fan_fmu(tmp_path, 2, name="with_b", xml=lambda x: _with_integer(x).replace(
        "<Integer start=\"1\"/>", "<Boolean start=\"false\"/>").replace('name="n"', 'name="b"'))
    with pytest.raises(HilError, match=r"--load-fmu-set b: a Boolean parameter \(true/false, 1/0\), got 2"):
        _cli_config(["--load-fmu", str(fmu), "--load-fmu-set", "b=2"])
    cfg = _cli_config(["--load-fmu", str(fmu), "--load-fmu-set", "b=true"])
    assert cfg.load_fmu_model is not None and cfg.load_fmu_model.params[0].value == 1.0


def test_isolation_none_is_explicit_and_gives_the_same_run(fan_fmus: dict[int, Path]) -> None:
    """`--load-fmu-isolation none` runs the FMU in the run's process (unprotected): the same periods as the
    contained default, bit for bit; an unknown mode is refused."""
    contained = _config(fan_fmus[2], settle_s=0.01, duration_s=0.01)
    assert contained.load_fmu is not None and contained.load_fmu.isolation == "process"
    inproc = _config(fan_fmus[2], settle_s=0.01, duration_s=0.01, isolation="none")
    a, b = run_closed_loop(contained).metrics, run_closed_loop(inproc).metrics
    assert a["end_code"] == b["end_code"] == 0
    assert a["load_torque_mean_nm"] == b["load_torque_mean_nm"] and a["speed_mean_rpm"] == b["speed_mean_rpm"]
    spec = _cli_config(["--load-fmu", str(fan_fmus[2]), "--load-fmu-isolation", "none"]).load_fmu
    assert spec is not None and spec.isolation == "none"
    with pytest.raises(HilError, match="--load-fmu-isolation must be one of process, none, got 'thread'"):
        load_fmu_spec(fan_fmus[2], None, None, isolation="thread")  # a config file's value (argparse checks the CLI)
