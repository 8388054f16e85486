"""The SIL target in its own process: a user firmware that crashes, aborts, overflows its stack or
never returns at step 500 (tests/firmware_board/misbehave/, built with `hil fw build`) ends `hil run` with exit 3
and the cause named, metrics.json and an MCAP of end_period + 1 periods; Ctrl-C/SIGTERM end a hung run within
1 s; a pytest session survives the crash (its JUnit XML lists every test)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.runlog.reader import read_periods
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.sim_target.fw_build import build_firmware
from tests.firmware_board._runs import rated
from tests.firmware_board.conftest import ROOT, need
from tests.testing.pytest_session import run_pytest

MISBEHAVE = Path(__file__).with_name("misbehave")
RUN = ["--controller=external", "--settle=0.02", "--duration=0.1"]  # 1200 periods; the firmware fails at 500
#: marks the `hil` processes this test process starts, and the SIL targets they start (they inherit it): the built
#: firmware is shared by content across checkouts (the per-user cache), so a second suite running at the same time
#: runs SIL targets of the same library path — a check by path alone saw those as left behind by this test
RUN_MARK = f"HIL_TEST_SIL_ISOLATION={os.getpid()}"


@pytest.fixture(scope="module")
def firmware() -> dict[str, Path]:
    need("host")
    kinds = ("crash", "abort", "overflow", "hang", "config")
    return {kind: build_firmware("host", MISBEHAVE / kind).path for kind in kinds}


def _hil_run(args: list[str], **kw: Any) -> subprocess.Popen[str]:
    name, value = RUN_MARK.split("=")
    return subprocess.Popen([sys.executable, "-m", "pmsm_hil.app.cli.main", "run", *args], cwd=ROOT, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env={**os.environ, name: value}, **kw)


def _outputs(out: Path) -> tuple[dict[str, Any], np.ndarray]:
    metrics = json.loads((out / "metrics.json").read_text())
    return metrics, read_periods(out / "run.mcap")


def _sil_processes(library: Path) -> list[int]:
    """Pids of live `hil target --sil LIBRARY` processes started by this test process's `hil run`s (`RUN_MARK`)."""
    pids = []
    for proc in Path("/proc").iterdir():
        try:
            cmd = (proc / "cmdline").read_bytes().split(b"\0")
            if b"--sil" in cmd and str(library).encode() in cmd \
                    and RUN_MARK.encode() in (proc / "environ").read_bytes().split(b"\0"):
                pids.append(int(proc.name))
        except OSError:
            continue
    return pids


def _cpu_s(pids: list[int]) -> float:
    """CPU time [s] the processes `pids` used (0 for none)."""
    total = 0
    for pid in pids:
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        total += int(fields[11]) + int(fields[12])  # utime, stime [clock ticks]
    return total / os.sysconf("SC_CLK_TCK")


def test_a_crash_at_step_500_ends_with_exit_3_and_every_period_logged(firmware: dict[str, Path],
                                                                      tmp_path: Path) -> None:
    out = tmp_path / "run"
    proc = _hil_run([f"--target=sil:{firmware['crash']}", *RUN, f"--out={out}", "--step-timeout=5"])
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 3, err
    assert "target crashed (SIGSEGV at period 500)" in err
    metrics, periods = _outputs(out)
    assert metrics["end_code"] == 3 and metrics["end_period"] == 500
    assert metrics["end_reason"].startswith("target crashed (SIGSEGV at period 500)")
    assert len(periods) == metrics["end_period"] + 1
    assert np.array_equal(periods["seq"], np.arange(501))
    assert metrics["safe_state"] is True and metrics["warnings"] == []


@pytest.mark.parametrize(("kind", "signame"), [("abort", "SIGABRT"), ("overflow", "SIGSEGV")])
def test_abort_and_stack_overflow_are_named_too(firmware: dict[str, Path], tmp_path: Path, kind: str,
                                                signame: str) -> None:
    """In this process (the runner's API): abort() or a stack overflow in the firmware's process leaves the
    caller standing."""
    res = run_closed_loop(rated(f"sil:{firmware[kind]}", settle_s=0.02, duration_s=0.1, controller="external",
                                out_dir=tmp_path, step_timeout_s=5.0))
    assert res.metrics["end_code"] == 3 and res.outcome.error is None
    assert res.metrics["end_reason"].startswith(f"target crashed ({signame} at period 500)")
    assert len(read_periods(tmp_path / "run.mcap")) == res.metrics["end_period"] + 1 == 501


def test_an_endless_loop_ends_with_exit_3_and_the_target_killed(firmware: dict[str, Path], tmp_path: Path) -> None:
    out = tmp_path / "run"
    t0 = time.monotonic()
    proc = _hil_run([f"--target=sil:{firmware['hang']}", *RUN, f"--out={out}", "--step-timeout=1"])
    _, err = proc.communicate(timeout=120)
    elapsed = time.monotonic() - t0
    assert proc.returncode == 3, err
    assert elapsed < 100.0  # a bound, not a speed: 45 s at load 12 (two `hil` start-ups, the 1 s step timeout)
    assert "target hung: its step for period 500 did not return within --step-timeout 1 s" in err
    metrics, periods = _outputs(out)
    assert metrics["end_code"] == 3 and len(periods) == metrics["end_period"] + 1 == 501
    assert _sil_processes(firmware["hang"]) == []  # killed, not left spinning


@pytest.mark.timing
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_ctrl_c_and_sigterm_end_a_hung_run_within_1_s(firmware: dict[str, Path], tmp_path: Path,
                                                      signum: int) -> None:
    out = tmp_path / "run"
    proc = _hil_run([f"--target=sil:{firmware['hang']}", *RUN, f"--out={out}", "--step-timeout=60"])
    deadline = time.monotonic() + 60.0
    # spinning in its endless loop: the run waits for it (2 s of CPU: the SIL process's own start-up, an
    # interpreter with numpy, takes up to ~1 s of CPU before period 0)
    while _cpu_s(_sil_processes(firmware["hang"])) < 2.0:
        assert proc.poll() is None and time.monotonic() < deadline, proc.communicate()[1]
        time.sleep(0.05)
    t0 = time.monotonic()
    os.kill(proc.pid, signum)
    _, err = proc.communicate(timeout=30)
    elapsed = time.monotonic() - t0
    assert proc.returncode == 130, err
    assert elapsed < 1.0, err
    assert (out / "metrics.json").is_file(), err
    metrics, periods = _outputs(out)
    # the interrupt comes while the run waits for step 500's Command: the log ends with period 499 (the waited-for
    # period is not kept: as a crash of a load FMU) or 500; either way it holds every period metrics.json counts
    assert metrics["end_code"] == 130 and len(periods) == metrics["end_period"] + 1 in (500, 501)
    assert _sil_processes(firmware["hang"]) == []


def test_a_pytest_session_survives_a_crashing_firmware(firmware: dict[str, Path], tmp_path: Path) -> None:
    s = run_pytest([str(MISBEHAVE / "sil_session_checks.py"), f"--hil-target=sil:{firmware['crash']}",
                    "--hil-controller=external"], tmp_path)
    assert s.outcomes("sil_session_checks") == {"test_before_the_crash": "passed", "test_the_crash": "passed",
                                                "test_after_the_crash": "passed"}, s.output[-4000:]
    assert s.rc == 0


def test_in_process_is_explicit(firmware: dict[str, Path]) -> None:
    with pytest.raises(ParameterError, match="--sil-in-process: only with --target sil:PATH"):
        rated(sil_in_process=True)
    with pytest.raises(ParameterError, match="--step-timeout"):
        rated(f"sil:{firmware['crash']}", step_timeout_s=0.0)
    # the library loaded into this process: the same firmware, no process around it (the first 300 periods)
    res = run_closed_loop(rated(f"sil:{firmware['crash']}", settle_s=0.01, duration_s=0.02,
                                controller="external", sil_in_process=True))
    assert res.metrics["end_code"] == 0 and res.metrics["link_spec"] == "virtual"


def test_an_idle_target_missing_a_command_is_not_hung(reference_sil: Path) -> None:
    """A Measurement lost on the way (injected): the firmware waits idle for frames, so the missing Command stays
    a contract violation (exit 4), not a hung target."""
    res = run_closed_loop(rated(f"sil:{reference_sil}", settle_s=0.01, duration_s=0.05, faults="drop.up=0.01,seed=3",
                                step_timeout_s=0.2))
    assert res.metrics["end_code"] == 4, res.metrics["end_reason"]
    assert "missing: no Command" in res.metrics["end_reason"]


def test_signal_handlers_are_restored(reference_sil: Path) -> None:
    before = (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM))
    res = run_closed_loop(rated(f"sil:{reference_sil}", settle_s=0.01, duration_s=0.01))
    assert res.metrics["end_code"] == 0
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before


def test_a_crash_while_being_configured(firmware: dict[str, Path], tmp_path: Path) -> None:
    res = run_closed_loop(rated(f"sil:{firmware['config']}", controller="external", out_dir=tmp_path))
    m = res.metrics
    assert m["end_code"] == 3 and m["end_period"] == -1 and res.outcome.error is None
    assert m["end_reason"].startswith("target crashed (SIGSEGV while being configured)")
    assert m["target_disabled"] is False  # nobody left to disable
    assert json.loads((tmp_path / "metrics.json").read_text())["end_code"] == 3
