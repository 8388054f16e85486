"""Ctrl-C and SIGTERM at any moment of `hil run`: the MCAP holds every period metrics.json counts, no
traceback, exit 130. A few tries here; `python -m tests.runner.interrupt_runs --tries 100` runs the
100-try check (figures in docs/runner.md)."""

from __future__ import annotations

import random
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from tests.runner.interrupt_runs import interrupt_once, wait_cpu

#: (variant, signal, to the process group as a terminal's Ctrl-C)
CASES = [("inproc", signal.SIGINT, False), ("inproc", signal.SIGTERM, True), ("python", signal.SIGTERM, False),
         ("udp-spawn", signal.SIGINT, True)]


@pytest.mark.parametrize(("variant", "sig", "group"), CASES, ids=[f"{v}-{s.name}{'-group' * g}" for v, s, g in CASES])
def test_an_interrupted_run_logs_every_period_it_counts(tmp_path: Path, variant: str, sig: signal.Signals,
                                                        group: bool) -> None:
    delay = random.Random(f"{variant}{sig}").uniform(0.0, 0.3)
    # forked with its imports made (tests/runner/hil_zygote.py): the signal comes mid-run, the start-up is the
    # next test's (fresh processes)
    t = interrupt_once(tmp_path / "run", variant, sig, delay, group=group, after_bytes=100_000, forked=True)
    assert "Traceback" not in t.stderr_tail
    assert t.rc == 130, t.stderr_tail
    assert t.mcap_periods is not None and t.mcap_periods > 0  # it was stopped mid-run
    assert t.end_period is not None and t.mcap_periods == t.end_period + 1 == t.metrics_periods
    assert t.seq_ok  # no gap: seq 0..n-1


@pytest.mark.parametrize("delay_s", [0.15, 0.4, 0.8])
def test_ctrl_c_in_the_first_second_is_one_line(tmp_path: Path, delay_s: float) -> None:
    """Ctrl-C while `hil run` imports, starts the logger or connects: exit 130, one line, no traceback; the
    files are consistent (or absent). The moment is `hil`'s own CPU time: by wall time, on a busy machine, the
    signal came while Python itself still started (a CPython fatal error, before any of `hil`'s code)."""
    t = interrupt_once(tmp_path / "run", "inproc", signal.SIGINT, delay_s, group=True, cpu_clock=True)
    assert "Traceback" not in t.stderr_tail and t.rc == 130, t.stderr_tail
    lines = t.stderr_tail.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("hil: ") and "interrupted" in lines[0], lines
    assert t.ok


def test_ctrl_c_early_in_replay_is_one_line(tmp_path: Path) -> None:
    assert main(["run", "--duration", "0.05", "--settle", "0", "--out", str(tmp_path / "r")]) == 0
    for delay in (0.2, 0.6):
        proc = subprocess.Popen([sys.executable, "-m", "pmsm_hil.app.cli.main", "replay",
                                 str(tmp_path / "r" / "run.mcap"), "--rerun-save", str(tmp_path / f"x{delay}.rrd")],
                                stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
        wait_cpu(proc, delay, 60.0)  # the replay's own CPU time (see the test above)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        text = err.decode(errors="replace")
        assert "Traceback" not in text
        assert proc.returncode in (0, 130), text  # 0: the replay was done before the signal


def test_main_turns_an_early_interrupt_into_exit_130(monkeypatch: pytest.MonkeyPatch,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    """Ctrl-C while the parser imports the subcommands (the first ~0.5 s of every `hil` command)."""
    from pmsm_hil.app.cli import main as main_module

    def interrupted(argv: list[str]) -> None:
        raise KeyboardInterrupt

    monkeypatch.setattr(main_module, "parser_for", interrupted)
    assert main(["run"]) == 130
    assert capsys.readouterr().err == "hil: interrupted\n"
    assert signal.getsignal(signal.SIGTERM) == signal.SIG_DFL  # main(argv) leaves the caller's handlers as found
    assert signal.getsignal(signal.SIGINT) == signal.default_int_handler


def test_an_error_an_interrupt_caused_is_still_an_interrupt(monkeypatch: pytest.MonkeyPatch,
                                                            capsys: pytest.CaptureFixture[str]) -> None:
    """numpy turns a KeyboardInterrupt inside its C import into an ImportError: after a signal, exit 130."""
    from pmsm_hil.app.cli import main as main_module

    def import_cut_by_ctrl_c(argv: list[str]) -> None:
        try:
            main_module._raise_interrupt(signal.SIGINT, None)
        except KeyboardInterrupt:
            raise ImportError("PyCapsule_Import could not import module datetime") from None

    monkeypatch.setattr(main_module, "_interrupted", [])
    monkeypatch.setattr(main_module, "parser_for", import_cut_by_ctrl_c)
    assert main(["run"]) == 130
    assert capsys.readouterr().err == "hil: interrupted\n"
    monkeypatch.setattr(main_module, "_interrupted", [])

    def plain_bug(argv: list[str]) -> None:
        raise ImportError("no interrupt here")

    monkeypatch.setattr(main_module, "parser_for", plain_bug)
    with pytest.raises(ImportError):
        main(["run"])
