"""The emulated MCU's endings told apart: a firmware fault (startup.c's handler ends QEMU with exit
code 64 + exception number through semihosting), a firmware that never returns from its step (QEMU alive and
executing), and a QEMU that dies (SIGKILL) each end with exit 3 and their own reason, the log complete up to
the last period; a firmware idle after a lost frame keeps its contract violation."""

from __future__ import annotations

import os
import re
import signal
from pathlib import Path

import pytest

from pmsm_hil.hil.runlog.reader import read_periods
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.sim_target.fw_build import build_firmware
from pmsm_hil.sim_target.qemu import fault_name
from tests.firmware_board._at_period import at_period
from tests.firmware_board._runs import rated
from tests.firmware_board.conftest import need

MISBEHAVE = Path(__file__).with_name("misbehave")


@pytest.fixture(scope="module")
def elf() -> dict[str, Path]:
    need("mps2-an386")
    return {kind: build_firmware("mps2-an386", MISBEHAVE / kind).path for kind in ("crash", "hang")}


def _run(target: str, out: Path, **kw: object) -> dict[str, object]:
    res = run_closed_loop(rated(target, settle_s=0.02, duration_s=0.05, out_dir=out, **kw))  # type: ignore[arg-type]
    assert res.outcome.error is None
    assert len(read_periods(out / "run.mcap")) == res.metrics["end_period"] + 1
    return res.metrics


def test_a_fault_is_named(elf: dict[str, Path], tmp_path: Path) -> None:
    m = _run(f"qemu:{elf['crash']}", tmp_path, controller="external")
    assert m["end_code"] == 3 and m["end_period"] == 500
    reason = str(m["end_reason"])
    assert re.match(r"target HardFault at pc 0x[0-9a-f]{8} \(hil_app_step\+0x[0-9a-f]+\), lr 0x[0-9a-f]{8} "
                    r"\(\w+\+0x[0-9a-f]+\), CFSR 0x00010000 \(UNDEFINSTR\), HFSR 0x40000000 \(FORCED\) "
                    r"at period 500: the firmware's fault handler", reason), reason


def test_a_hang_is_named(elf: dict[str, Path], tmp_path: Path) -> None:
    m = _run(f"qemu:{elf['hang']}", tmp_path, controller="external")
    assert m["end_code"] == 3 and m["end_period"] == 500
    assert str(m["end_reason"]).startswith("target hung: its step for period 500 did not return")


def test_a_dead_qemu_is_named(reference_elf: Path, tmp_path: Path) -> None:
    killed: list[int] = []

    def kill_qemu(done: int) -> None:  # in mid-run, at period 100 of 700
        me = os.getpid()
        for pid in Path(f"/proc/{me}/task/{me}/children").read_text().split():
            if b"qemu-system-arm" in Path(f"/proc/{pid}/cmdline").read_bytes():
                os.kill(int(pid), signal.SIGKILL)
                killed.append(int(pid))

    with at_period(100, kill_qemu) as counter:
        res = run_closed_loop(rated(f"qemu:{reference_elf}", settle_s=0.02, duration_s=0.05, out_dir=tmp_path),
                              counter=counter)
    assert killed
    m = res.metrics
    assert m["end_code"] == 3 and res.outcome.error is None
    assert str(m["end_reason"]).startswith("QEMU died (SIGKILL")
    assert len(read_periods(tmp_path / "run.mcap")) == m["end_period"] + 1


def test_an_idle_firmware_keeps_its_violation(reference_elf: Path, tmp_path: Path) -> None:
    m = _run(f"qemu:{reference_elf}", tmp_path, faults="drop.up=0.01,seed=3")
    assert m["end_code"] == 4 and "missing: no Command" in str(m["end_reason"])


def test_fault_exit_codes() -> None:
    assert fault_name(64 + 3) == "HardFault" and fault_name(64 + 6) == "UsageFault"
    assert fault_name(1) is None and fault_name(0) is None and fault_name(-9) is None


def test_fault_report_is_decoded() -> None:
    from pmsm_hil.sim_target.qemu import describe_fault

    line = ("qemu: warning: x\nHIL-FAULT exc=5 pc=0000021c lr=00000a41 cfsr=00008200 hfsr=40000000 mmfar=e000edf8 "
            "bfar=20040000\n")
    assert describe_fault(line) == ("BusFault at pc 0x0000021c, lr 0x00000a41, CFSR 0x00008200 (PRECISERR BFARVALID), "
                                    "HFSR 0x40000000 (FORCED), BFAR 0x20040000")
    assert describe_fault("no report") is None


def test_cli_fault_exit_3_names_the_pc(elf: dict[str, Path], tmp_path: Path,
                                       capsys: pytest.CaptureFixture[str]) -> None:
    """`hil run --target qemu:USER.elf` runs controller external without being told, and a fault at step 500
    ends with exit 3 and the faulting pc named."""
    from pmsm_hil.app.cli.main import main

    rc = main(["run", "--target", f"qemu:{elf['crash']}", "--duration", "0.05", "--settle", "0.02",
               "--out", str(tmp_path / "run")])
    out = capsys.readouterr()
    assert rc == 3, out.err
    assert re.search(r"target HardFault at pc 0x[0-9a-f]{8} \(hil_app_step\+0x[0-9a-f]+\)", out.out + out.err)
