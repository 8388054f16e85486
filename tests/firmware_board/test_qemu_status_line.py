"""`hil run --target qemu:FW.elf` on a terminal (a pty): the status line is there from the start — drawn before
QEMU boots and the link is set up (seconds), naming that phase — and the run's periods follow it; within 1 s of the
start on an idle enough machine (the `timing` test)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from tests.cli_status.pty_run import PtyOutput, run_on_pty
from tests.firmware_board.conftest import need


@pytest.fixture(scope="module")
def qemu_run(reference_elf: Path) -> PtyOutput:
    need("mps2-an386")
    return run_on_pty(["run", "--target", f"qemu:{reference_elf}", "--settle", "0.02", "--duration", "0.03",
                       "--no-log"], timeout_s=300.0)


def test_the_starting_phase_is_drawn_before_the_target_is_up(qemu_run: PtyOutput) -> None:
    out = qemu_run
    assert out.code == 0, out.text
    first = out.first("hil run: starting")
    booting = out.first("starting target qemu:")
    configuring = out.first("hil run: configuring target")
    done = out.first("500/500 periods")
    assert None not in (first, booting, configuring, done), out.text
    assert first <= booting <= configuring <= done  # type: ignore[operator]
    assert out.chunks[0][1].decode(errors="replace").startswith("hil run: starting")  # the first thing drawn
    assert "hil run: completed" in out.text


@pytest.mark.timing
def test_the_status_line_is_drawn_within_one_second(qemu_run: PtyOutput) -> None:
    first = qemu_run.first("hil run: starting")
    assert first is not None and first < 1.0, f"first status line after {first} s"


def test_the_count_moves_between_blocks(qemu_run: PtyOutput) -> None:
    """The 500 periods are one block of the C loop; the line reads the loop's live counter at each redraw, so a
    run that lasts more than a second shows counts between 0 and 500."""
    out = qemu_run
    running, done = out.first("hil run: running"), out.first("500/500 periods")
    assert running is not None and done is not None
    counts = {int(n) for n in re.findall(r"(\d+)/500 periods", out.text)}
    if done - running > 1.0:
        assert counts - {0, 500}, sorted(counts)
