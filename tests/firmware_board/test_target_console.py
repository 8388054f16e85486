"""A SIL target's stdout and stderr are drained all the time: a firmware printing 1 kB per step
(tests/firmware_board/misbehave/print) completes — undrained, its 64 KiB pipe filled within ~60 periods and the
run ended as a false `missing` violation — and its lines are in the run's MCAP (`/target/console`)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.runlog.reader import read_periods, read_topic_messages
from pmsm_hil.hil.runlog.topics import TOPIC_CONSOLE
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.sim_target.fw_build import build_firmware
from tests.firmware_board._runs import rated
from tests.firmware_board.conftest import need

PRINT = Path(__file__).with_name("misbehave") / "print"
LINE = "step {:06d} line {}: " + "0" * 107


@pytest.fixture(scope="module")
def printing() -> Path:
    need("host")
    return build_firmware("host", PRINT).path


def test_a_firmware_printing_1_kb_per_step_completes_and_its_lines_are_logged(printing: Path, tmp_path: Path) -> None:
    res = run_closed_loop(rated(f"sil:{printing}", controller="external", settle_s=0.02, duration_s=0.1,
                                out_dir=tmp_path))
    m = res.metrics
    assert m["end_code"] == 0, m["end_reason"]
    steps = len(read_periods(tmp_path / "run.mcap"))
    assert steps == m["end_period"] + 1 == 1200
    lines = [json.loads(msg.data) for msg in read_topic_messages(tmp_path / "run.mcap", TOPIC_CONSOLE)]
    assert len(lines) >= 8 * steps  # ~1.2 MB through a 64 KiB pipe
    texts = [line["text"] for line in lines]
    assert LINE.format(0, 0) in texts and LINE.format(steps - 1, 7) in texts
    assert {line["stream"] for line in lines} == {"stdout"}
    assert [line["seq"] for line in lines] == list(range(len(lines)))
    assert not any(w.startswith("target console") for w in m["warnings"])


def test_verbose_prints_the_lines_on_the_terminal(printing: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`hil run --verbose` (its main(), in this process: the lines are the runner's, not the interpreter's)."""
    argv = ["run", f"--target=sil:{printing}", "--controller=external", "--settle=0.01", "--duration=0.01", "--no-log"]
    assert main([*argv, "--verbose"]) == 0
    assert f"[target] {LINE.format(0, 0)}" in capsys.readouterr().err
    assert main(argv) == 0
    assert "[target]" not in capsys.readouterr().err


def test_qemus_console_is_logged_too(tmp_path: Path) -> None:
    """QEMU's semihosting console (a file: it never blocks) goes to `/target/console` at the end of the run: the
    fault handler's report line of a firmware that faults at step 500."""
    need("mps2-an386")
    elf = build_firmware("mps2-an386", PRINT.with_name("crash")).path
    res = run_closed_loop(rated(f"qemu:{elf}", controller="external", settle_s=0.02, duration_s=0.05,
                                out_dir=tmp_path))
    assert res.metrics["end_code"] == 3, res.metrics["end_reason"]
    lines = [json.loads(msg.data) for msg in read_topic_messages(tmp_path / "run.mcap", TOPIC_CONSOLE)]
    assert any(line["text"].startswith("HIL-FAULT exc=3 pc=") and line["stream"] == "stderr" for line in lines), lines
