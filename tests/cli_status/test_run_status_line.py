"""`hil run`'s live status line: on a terminal (a pty) it is drawn from the start (the phase first, then periods
done / total, simulated time, rate, speed and torque) and ends with the run; with stdout not a terminal, or with
--quiet, nothing of it is written."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.app.cli.status_line import StatusLine, status_wanted
from tests.cli_status.pty_run import run_on_pty

#: a short in-process run of 3000 periods (three blocks of the C loop)
SHORT = ["run", "--settle", "0.1", "--duration", "0.2", "--no-log"]
#: what only the status line draws: its phases, its counts
STATUS = re.compile(r"hil run: (starting|checking|configuring|running|writing|completed)|\d+/\d+ periods \[")


def test_on_a_terminal_the_status_line_shows_the_phase_then_the_periods() -> None:
    out = run_on_pty(SHORT)
    assert out.code == 0, out.text
    text = out.text
    assert "hil run: starting target" in text or "hil run: checking options" in text
    first = min(t for t in (out.first("hil run: checking options"), out.first("hil run: starting target"))
                if t is not None)
    done = out.first("3000/3000 periods")
    assert done is not None and first < done, text
    line = text[text.index("3000/3000 periods"):].split("\r")[0].split("\n")[0]
    figures = r"sim 0\.300/0\.300 s, [\d.]+k? periods/s \([\d.]+× real time\), \d+ rpm, -?[\d.]+ N·m"
    assert re.search(figures, line), line
    assert "hil run: completed" in text


def test_quiet_on_a_terminal_draws_no_status_line() -> None:
    out = run_on_pty([*SHORT, "--quiet"])
    assert out.code == 0, out.text
    assert STATUS.search(out.text) is None, out.text
    assert "speed" in out.text  # the metrics table is there


def test_no_status_line_when_stdout_is_not_a_terminal(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(SHORT) == 0
    captured = capsys.readouterr()
    for stream in (captured.out, captured.err):
        assert STATUS.search(stream) is None and "\r" not in stream, stream
    assert "speed" in captured.out


def test_status_wanted_needs_both_streams_on_a_terminal(tmp_path: Path) -> None:
    class Tty:
        def __init__(self, tty: bool) -> None:
            self.tty = tty

        def isatty(self) -> bool:
            return self.tty

    assert status_wanted(False, Tty(True), Tty(True))  # type: ignore[arg-type]
    assert not status_wanted(True, Tty(True), Tty(True))  # type: ignore[arg-type]
    assert not status_wanted(False, Tty(False), Tty(True))  # type: ignore[arg-type]
    assert not status_wanted(False, Tty(True), Tty(False))  # type: ignore[arg-type]
    line = StatusLine("x", enabled=False)  # disabled: every call is a no-op, nothing is imported or drawn
    line.phase("p")
    line.total(3, "runs")
    line.update(1, "f")
    line.warn("w")
    line.close()
