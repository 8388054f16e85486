"""Real CAN tools on our bus (vcan0, `.ci/vcan-vm`): can-utils `candump -L` records a `hil run` over SocketCAN
and `cantools decode src/pmsm_hil/protocol/hil.dbc` names its frames; `cansend` of hand-made Setpoint frames reaches a
running `hil target`, whose own rules answer them; docs/logging.md's lossless capture recipe (candump -d -r) holds:
the capture has every frame the run logged, no drop, and replays to the run's currents."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import can
import cantools
import pytest

from pmsm_hil.hil.runlog import read_frames
from pmsm_hil.hil.runlog.can_log import export_frames
from pmsm_hil.hil.runner.replay_run import replay_run

ROOT = Path(__file__).resolve().parents[2]
DBC = ROOT / "src" / "pmsm_hil" / "protocol" / "hil.dbc"
HIL = [sys.executable, "-m", "pmsm_hil.app.cli.main"]
pytestmark = [
    pytest.mark.skipif(not Path("/sys/class/net/vcan0").exists(),
                       reason="no SocketCAN interface vcan0 (kernel without vcan; `ip link add vcan0 type vcan`; "
                              ".ci/vcan-vm runs these)"),
    pytest.mark.skipif(shutil.which("candump") is None or shutil.which("cansend") is None,
                       reason="can-utils not installed (apt-get install can-utils; .ci/run installs it)"),
]


def _cantools_cli() -> list[str]:
    return [sys.executable, "-m", "cantools"]


def _captured_run(tmp_path: Path, capture: Path, *candump_opts: str) -> tuple[Path, bytes]:
    """A 0.012 s `hil run` over socketcan:vcan0,fd=true with `candump -L -r 4194304 *candump_opts vcan0` writing
    `capture` around it; returns the run's folder and candump's stderr."""
    with capture.open("wb") as sink:
        # -r: candump's own receive buffer (default 212 992 bytes, ~278 frames) for a burst of the run's frames;
        # without it candump under TCG lost 1354 of the 4231 frames of a 0.2 s run (its kernel dropped them)
        dump = subprocess.Popen(["candump", "-L", "-r", "4194304", *candump_opts, "vcan0"], stdout=sink,
                                stderr=subprocess.PIPE)
    try:
        time.sleep(0.5)  # candump has bound its socket
        out = tmp_path / "run"
        r = subprocess.run([*HIL, "run", "--link", "socketcan:vcan0,fd=true", "--target", "spawn",
                            "--duration", "0.012", "--settle", "0.002", "--out", str(out),
                            "--lockstep-timeout", "10"],  # a VM under TCG on a loaded host stalls
                           capture_output=True, text=True, timeout=600)
        assert r.returncode == 0, r.stdout + r.stderr
        time.sleep(0.5)
    finally:
        dump.send_signal(signal.SIGINT)
        _, err = dump.communicate(timeout=10)
    return out, err


def test_candump_records_a_run_and_cantools_decodes_it(tmp_path: Path) -> None:
    log = tmp_path / "candump.log"
    out, _ = _captured_run(tmp_path, log)
    text = log.read_text()
    decoded = subprocess.run([*_cantools_cli(), "decode", str(DBC)], input=text, capture_output=True, text=True,
                             timeout=300)
    assert decoded.returncode == 0, decoded.stderr
    for name in ("MeasFd(", "CmdFd(", "Setpoint(", "HeartbeatTarget("):
        assert name in decoded.stdout, name  # the Measurement and Command frames of the run, by name
    db = cantools.database.load_file(DBC)
    by_name: dict[str, int] = {}
    for msg in can.CanutilsLogReader(log):
        m = db.get_message_by_frame_id(msg.arbitration_id)
        values = m.decode(bytes(msg.data), decode_choices=False)
        for sig in m.signals:  # every signal within its DBC range
            if sig.minimum is not None and sig.maximum is not None:
                assert sig.minimum <= values[sig.name] <= sig.maximum, (m.name, sig.name, values[sig.name])
        by_name[m.name] = by_name.get(m.name, 0) + 1
    frames = read_frames(out / "run.mcap")
    cmd_fd = db.get_message_by_name("CmdFd").frame_id
    assert by_name["CmdFd"] == int((frames["arbitration_id"] == cmd_fd).sum()) > 50  # what the run logged


def _wait_for(bus: can.BusABC, frame_id: int, timeout_s: float) -> can.Message:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        msg = bus.recv(0.1)
        if msg is not None and msg.arbitration_id == frame_id:
            return msg
    raise AssertionError(f"no frame 0x{frame_id:03X} within {timeout_s} s")


def test_cansend_setpoints_are_answered_by_a_running_target() -> None:
    db = cantools.database.load_file(DBC)
    target = subprocess.Popen([*HIL, "target", "--link", "socketcan:vcan0", "--idle-timeout", "120"],
                              stdout=subprocess.PIPE, text=True, env={**os.environ, "PYTHONUNBUFFERED": "1"})
    try:
        assert target.stdout is not None and target.stdout.readline().startswith("ready"), "target not ready"
        with can.Bus(interface="socketcan", channel="vcan0") as bus:
            # enable 1, mode 7 (no such mode), reference 0, controller 1 mpcc: the target's rule answers Fault
            subprocess.run(["cansend", "vcan0", "200#01070000000001"], check=True)
            fault = db.decode_message("FaultTarget", _wait_for(bus, 0x011, 30).data, decode_choices=False)
            assert (fault["code"], fault["detail"]) == (5, 7)  # invalid_config, the rejected mode
            # enable 0: the disabling Setpoint is answered with a HeartbeatTarget in state idle
            subprocess.run(["cansend", "vcan0", "200#00000000000001"], check=True)
            beat = db.decode_message("HeartbeatTarget", _wait_for(bus, 0x701, 30).data, decode_choices=False)
            assert beat["state"] == 1
    finally:
        target.terminate()
        target.wait(30)


def test_the_lossless_candump_recipe_captures_every_frame_and_replays_the_run(tmp_path: Path) -> None:
    """docs/logging.md, "Capturing a run losslessly with candump": `candump -L -d -r 4194304` started before the run
    holds as many lines as `hil mcap export --format candump` exports, reports no drop, and `hil replay` of the
    capture with the run's log gives back the logged currents (within 1e-6 A)."""
    capture = tmp_path / "capture.log"
    out, err = _captured_run(tmp_path, capture, "-d")
    lines = capture.read_text().splitlines()
    assert not [ln for ln in lines if "DROPCOUNT" in ln] and b"DROPCOUNT" not in err, err
    exported = export_frames(out / "run.mcap", "candump", tmp_path / "frames.log")
    assert len(lines) == exported > 50  # the check the recipe gives: N lines, N the frames the run logged
    done = replay_run(out / "run.mcap", tmp_path / "replay.csv", capture=capture)
    assert done.result.gaps == 0 and done.compared > 50
    assert done.max_error_a <= 1e-6, done.max_error_a
