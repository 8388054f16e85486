"""The emulated Cortex-M4F (QEMU mps2-an386): the reference firmware built for the MCU, lockstep over the
emulated UART (COBS + CRC-16 in C), holds the rated point like the in-process run; its per-step instruction
counts (QEMU plugin) are deterministic; QEMU never outlives the host."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.sim_target.qemu import QemuError, QemuTarget
from tests.firmware_board._runs import assert_like, metrics, rated


def test_reference_qemu_like_inproc(reference_elf: Path, tmp_path: Path) -> None:
    # 700 periods, not the rated 2000: the acceptance compares window means and ripple, which agree at any length
    # (the reference firmware's control is the in-process one's: equal to the last bit at 0.05 s as at 0.15 s), and
    # each QEMU period costs ~1.5 CPU-ms
    ref = metrics(rated(settle_s=0.02, duration_s=0.05))
    m = metrics(rated(f"qemu:{reference_elf}", settle_s=0.02, duration_s=0.05, out_dir=tmp_path / "q"))
    assert_like(m, ref)
    assert m["dut_violations"] == 0 and m["link_spec"] == "serial:qemu-uart0"
    assert m["loop"] == "native"  # the C loop, through its callback link to the UART socket
    ins = m["exec_instructions"]
    assert 500 < ins["median"] < 5000 and ins["median"] <= ins["p99"] <= ins["max"]
    assert ins["steps"] == round(0.05 / 1e-4)  # the metrics window
    assert m["exec_time_us"]["median"] == pytest.approx(ins["median"] / 168.0)
    assert m["mcu_clock_hz"] == 168e6 and "estimate" in m["exec_time_model"]
    assert (tmp_path / "q" / "run.mcap").stat().st_size > 0


def test_instruction_counts_deterministic(reference_elf: Path) -> None:
    # 250 periods each (not 500): the counts repeat period by period, whatever the length
    a = metrics(rated(f"qemu:{reference_elf}", settle_s=0.005, duration_s=0.02))
    b = metrics(rated(f"qemu:{reference_elf}", settle_s=0.005, duration_s=0.02, mcu_clock_hz=84e6))
    assert a["exec_instructions"] == b["exec_instructions"]
    assert a["torque_ripple_rms_nm"] == b["torque_ripple_rms_nm"]  # lockstep: the whole run repeats
    assert b["exec_time_us"]["median"] == pytest.approx(2 * a["exec_time_us"]["median"])


def test_cli_qemu_run(reference_elf: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["run", "--target", f"qemu:{reference_elf}", "--mcu-clock", "100MHz", "--settle", "0.005",
                 "--duration", "0.02", "--no-log", "--json", str(tmp_path / "m.json")])
    assert code == 0
    assert "exec instructions" in capsys.readouterr().out


def test_qemu_dies_with_host(reference_elf: Path) -> None:
    """kill -9 of the host process leaves no QEMU behind (PR_SET_PDEATHSIG)."""
    code = ("import sys, time\nfrom pmsm_hil.sim_target.qemu import QemuTarget\n"
            f"q = QemuTarget({str(reference_elf)!r}, count_instructions=False)\n"
            "print(q.process.pid, flush=True)\ntime.sleep(60)\n")
    host = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    assert host.stdout is not None
    pid = int(host.stdout.readline())
    os.kill(host.pid, signal.SIGKILL)
    host.wait()
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return
        time.sleep(0.05)
    os.kill(pid, signal.SIGKILL)
    pytest.fail("QEMU outlived its host")


def test_qemu_errors(tmp_path: Path, reference_sil: Path) -> None:
    with pytest.raises(QemuError, match="not found"):
        QemuTarget(tmp_path / "none.elf")
    with pytest.raises(QemuError):
        QemuTarget(reference_sil)  # a host library: not an mps2-an386 firmware


def test_mailbox_transport_equals_uart(reference_elf: Path) -> None:
    """The PSRAM mailbox carries the same frames: a lockstep run is identical to the UART run."""
    uart = metrics(rated(f"qemu:{reference_elf}", settle_s=0.01, duration_s=0.03))
    mbox = metrics(rated(f"qemu:{reference_elf}", settle_s=0.01, duration_s=0.03, link="mailbox"))
    assert mbox["link_spec"] == "mailbox:qemu-psram"
    for key in ("torque_mean_nm", "torque_ripple_rms_nm", "speed_mean_rpm", "exec_instructions"):
        assert mbox[key] == uart[key], key


def test_qemu_config_errors(reference_elf: Path) -> None:
    from pmsm_hil.hil.errors import ParameterError

    with pytest.raises(ParameterError, match="lockstep only"):
        rated(f"qemu:{reference_elf}", mode="realtime")
    with pytest.raises(ParameterError, match="emulated UART"):
        rated(f"qemu:{reference_elf}", link="udp")
    with pytest.raises(ParameterError, match="--target"):
        rated("qemu:")


def test_mailbox_doorbells_and_prompt_stop(reference_elf: Path) -> None:
    """The mailbox's doorbells (host FIFOs the firmware reads and writes with semihosting): requests are answered
    with both ends asleep between them, and QEMU stops at once on close (the firmware, blocked on its doorbell,
    reads end-of-file and halts) rather than after the SIGTERM grace period."""
    from pmsm_hil.sim_target.qemu import MailboxLink

    q = QemuTarget(reference_elf, count_instructions=False, transport="mailbox")
    try:
        link = q.mailbox_link()
        assert isinstance(link, MailboxLink)
        for _ in range(3):
            link.send([])
            time.sleep(0.01)  # the firmware answers and sleeps on its doorbell; the host's wait is a sleep too
            deadline = time.monotonic() + 5
            while link.pending and time.monotonic() < deadline:
                assert link.poll() is None  # an empty request has an empty reply
            assert not link.pending
        link.close()
    finally:
        t0 = time.monotonic()
        q.close()
        assert time.monotonic() - t0 < 2.5
