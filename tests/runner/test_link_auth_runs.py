"""Authenticated frames in runs: on by default for spawned targets over UDP and serial, a
pre-shared key for external ones; Python and C ends interoperate; a wrong key is a clear error; a privileged
spoofer on the loopback (raw sockets: forged, stripped and replayed datagrams with the genuine addresses) changes
nothing and is counted."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.protocol.links.wire_bus import free_udp_ports

KEY = "5e" * 32
SPOOF = Path(__file__).with_name("udp_spoof.py")


def _metrics(path: Path) -> dict:  # type: ignore[type-arg]
    return dict(json.loads(path.read_text(encoding="utf-8")))


def _assert_clean(m: dict, speed_rpm: float = 1500.0) -> None:  # type: ignore[type-arg]
    assert m["end_code"] == 0, m["end_reason"]
    assert m["link_authenticated"] is True and m["safe_stop_confirmed"] is True
    assert abs(m["speed_mean_rpm"] - speed_rpm) <= 15.0
    assert m["link"]["auth_failed"] == m["link"]["auth_replayed"] == 0


@pytest.mark.parametrize("link", ["udp", "serial:pty"])
def test_spawned_targets_authenticate_by_default_and_auth_off_turns_it_off(link: str, tmp_path: Path) -> None:
    out = tmp_path / "m.json"
    assert main(["run", "--link", link, "--target", "spawn", "--settle", "0.02", "--duration", "0.05",
                 "--no-log", "--json", str(out)]) == 0
    m = _metrics(out)
    _assert_clean(m)
    assert m["target_link"]["auth_failed"] == m["target_link"]["auth_replayed"] == 0
    assert m["target_link"]["frames_rx"] == m["link"]["frames_tx"]
    assert m["link_auth_dropped"] == {"to_target": 0, "to_host": 0}
    assert main(["run", "--link", f"{link},auth=off", "--target", "spawn", "--settle", "0.02", "--duration", "0.02",
                 "--no-log", "--json", str(out)]) == 0
    assert _metrics(out)["link_authenticated"] is False


@contextmanager
def _external_target(link: str, native: bool) -> Iterator[subprocess.Popen[str]]:
    cmd = [sys.executable, "-m", "pmsm_hil.app.cli.main", "target", "--link", link, "--idle-timeout", "60",
           *(["--native"] * native)]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        ready = proc.stdout.readline()
        assert ready.startswith("ready") and KEY not in ready, ready  # the key is never echoed
        yield proc
    finally:
        proc.terminate()
        proc.wait(timeout=30)


@pytest.mark.parametrize("native_target", [True, False], ids=["c-target", "python-target"])
def test_a_pre_shared_key_with_an_external_target_python_and_c_ends_interoperate(native_target: bool,
                                                                                 tmp_path: Path) -> None:
    """The host configures the target from Python (Python link <-> the target) and runs the periods from the C
    loop (C link <-> the target): against the C target and the Python one, both ways are covered."""
    a, b = free_udp_ports()
    key_file = tmp_path / "k.hex"
    key_file.write_text(KEY + "\n", encoding="ascii")
    with _external_target(f"udp:{b}:{a},keyfile={key_file}", native_target):
        for run in ("one", "two"):  # a session per run: the second run's freshness counts from 1 again
            out = tmp_path / f"{run}.json"
            assert main(["run", "--link", f"udp:{a}:{b},key={KEY}", "--target", "external", "--settle", "0.02",
                         "--duration", "0.05", "--out", str(tmp_path / run), "--json", str(out)]) == 0
            m = _metrics(out)
            _assert_clean(m)
            assert m["loop"] == "native" and KEY not in m["link_spec"]
            assert KEY not in (tmp_path / run / "metrics.json").read_text(encoding="utf-8")


@pytest.mark.parametrize("native_target", [True, False], ids=["c-target", "python-target"])
def test_a_wrong_pre_shared_key_fails_the_run_with_a_clear_error(native_target: bool,
                                                                 capsys: pytest.CaptureFixture[str]) -> None:
    a, b = free_udp_ports()
    with _external_target(f"udp:{b}:{a},key={'77' * 32}", native_target) as proc:
        rc = main(["run", "--link", f"udp:{a}:{b},key={KEY}", "--target", "external", "--duration", "0.01",
                   "--no-log"])
        err = capsys.readouterr().err
        assert rc != 0 and "its authentication key differs from this end's" in err, err
        assert KEY not in err and proc.poll() is None  # the target stays up for a run with the right key


def test_serial_pty_c_host_loop_against_the_python_target(tmp_path: Path) -> None:
    master, slave = os.openpty()
    try:
        with _external_target(f"serial:{os.ttyname(slave)},key={KEY}", False):
            out = tmp_path / "m.json"
            assert main(["run", "--link", f"serial:fd:{master},key={KEY}", "--target", "external", "--settle",
                         "0.02", "--duration", "0.05", "--no-log", "--json", str(out)]) == 0
        m = _metrics(out)
        _assert_clean(m)
        assert m["loop"] == "native"
    finally:
        os.close(slave)


def _can_spoof() -> bool:
    try:
        socket.socket(socket.AF_INET, socket.SOCK_RAW, socket.IPPROTO_RAW).close()
        socket.socket(socket.AF_PACKET, socket.SOCK_RAW).close()
    except (PermissionError, OSError, AttributeError):
        return False
    return True


@pytest.mark.timing
@pytest.mark.skipif(not _can_spoof(), reason="needs CAP_NET_RAW (a privileged spoofer)")
def test_a_privileged_spoofer_with_the_genuine_addresses_changes_nothing_and_is_counted(tmp_path: Path) -> None:
    a, b = free_udp_ports()
    spoof = subprocess.Popen([sys.executable, str(SPOOF), str(a), str(b), "20000", "60"], stdout=subprocess.PIPE,
                             text=True)
    try:
        assert spoof.stdout is not None and spoof.stdout.readline().strip() == "capturing"
        out = tmp_path / "m.json"
        rc = main(["run", "--link", f"udp:{a}:{b}", "--target", "spawn", "--settle", "0.05", "--duration", "2",
                   "--no-log", "--json", str(out)])
    finally:
        spoof.terminate()
        report = spoof.communicate(timeout=30)[0]
    assert int(report.split()[1]) > 0, report
    m = _metrics(out)
    assert rc == m["end_code"] == 0, m["end_reason"]
    assert abs(m["speed_mean_rpm"] - 1500.0) <= 15.0 and abs(m["torque_mean_nm"] - 7.0) <= 0.14
    target = m["target_link"]
    # every spoofed datagram was dropped at the end it reached, for its authentication, and counted
    assert m["link"]["auth_failed"] > 0 and m["link"]["auth_replayed"] > 0
    assert target["auth_failed"] > 0 and target["auth_replayed"] > 0
    assert m["link_auth_dropped"]["to_host"] > 0 and m["link_auth_dropped"]["to_target"] > 0
    assert target["frames_rx"] == m["link"]["frames_tx"] and m["link"]["frames_rx"] == target["frames_tx"]
    # no genuine frame lost (the kernel may drop spoofed datagrams while a receive buffer is full: socket_drops)
    assert m["link"]["dropped"] == target["dropped"] == 0


def test_serial_with_a_wrong_key_says_so_when_the_target_stays_silent() -> None:
    """Serial has no handshake: a target with another key drops every frame and never answers; the host's error
    names the key, and counts the frames of another key it dropped itself."""
    from pmsm_hil.hil.runner.target_client import DutViolationError, TargetClient
    from pmsm_hil.protocol.codec import FrameCodec
    from pmsm_hil.protocol.ids import ParamId
    from pmsm_hil.protocol.links import open_link
    from tests.protocol.wire_oracle import Sealer, encode_packet, pack_frame

    master, slave = os.openpty()
    link = open_link(f"serial:fd:{master},key={KEY}", "host")
    try:
        os.write(slave, encode_packet(Sealer(bytes(32), "target").seal(pack_frame(0x211, bytes(6), 0, 0))))
        with pytest.raises(DutViolationError, match=r"with the same key.*1 frame\(s\) from it failed authentication"):
            TargetClient(link, FrameCodec("canfd")).configure({ParamId.RS: 0.1}, timeout_s=0.2)
    finally:
        link.close()
        os.close(slave)
