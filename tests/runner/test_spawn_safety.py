"""Spawned targets talk only to their host and never outlive it: forged datagrams never arrive, a target
that cannot bind its port ends the run with its error, a killed host leaves no target behind."""

from __future__ import annotations

import binascii
import functools
import os
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner import loop as loop_module
from pmsm_hil.hil.runner import loop_run
from pmsm_hil.hil.runner import run as run_module
from pmsm_hil.hil.runner.run import RunResult, run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.safe_stop import disable_and_confirm
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.hil.runner.target_client import TargetError
from pmsm_hil.hil.runner.target_setup import TargetConnection, connect_target
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.ids import ControllerId, ParamId
from pmsm_hil.protocol.links.wire_bus import HilUdpBus, free_udp_ports
from pmsm_hil.protocol.messages import Command, ConfigParam, Setpoint
from tests.oracle import closed_loop as python_loop
from tests.runner.hil_zygote import start_hil
from tests.runner.interrupt_runs import cpu_seconds

#: period-record fields measured on the wall clock (everything else of a lockstep run is deterministic)
WALL_FIELDS = {"exec_time_ns", "exec_split_ns", "late", "missed"}
WALL_METRICS = {"wall_time_s", "loop_rate_hz", "total_wall_time_s", "loop_rate_total_hz", "exec_time_us",
                "exec_split_us", "exec_time_first_us", "command_wait_max_us", "link", "safe_stop_wait_ms",
                "target_link"}


def _cfg(link: str, settle_s: float = 0.05, duration_s: float = 0.1) -> RunConfig:
    sc = load_scenario("steady").with_overrides(settle_s=settle_s, duration_s=duration_s)
    return replace(RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc), link=link, target="spawn")


def _forged_datagrams(session: int) -> tuple[list[bytes], list[bytes]]:
    """(to the target, to the host): the reported frames, in the old format, with a guessed session and
    with the run's real session (as if it had leaked); a HELLO trying to start a new session."""
    codec = FrameCodec("canfd")
    to_target = codec.encode(Setpoint(enable=False, mode=0, reference=0.0, controller_id=int(ControllerId.MPCC)))
    to_target += codec.encode(ConfigParam(param_id=int(ParamId.RS), value=1000.0))
    to_host = [f for seq in range(0, 3000, 300) for f in codec.encode(Command(seq, (7,), (100_000,)))]

    def datagrams(frames: list[Any]) -> list[bytes]:
        out = [struct.pack("<I4sBBI", 0, b"HILS", 1, 1, 0x5EED)]
        for i, fr in enumerate(frames):
            body = struct.pack("<IBBB", fr.arbitration_id, 3 if fr.is_fd else 0, i & 0xFF, len(fr.data)) + fr.data
            crc = binascii.crc_hqx(body, 0xFFFF).to_bytes(2, "big")
            out += [body, struct.pack("<I", 0x5EED) + body + crc, struct.pack("<I", session) + body + crc]
        return out

    return datagrams(to_target), datagrams(to_host)


def _spoofed_run(cfg: RunConfig, monkeypatch: pytest.MonkeyPatch) -> tuple[RunResult, TargetConnection, dict[str, int]]:
    """Run `cfg` while another socket forges datagrams to both ends; returns the run, its connection and the
    number of datagrams sent to each port."""
    seen: list[TargetConnection] = []

    def capture(*args: Any, **kwargs: Any) -> TargetConnection:
        conn = connect_target(*args, **kwargs)
        seen.append(conn)
        return conn

    monkeypatch.setattr(run_module, "connect_target", capture)  # the Python loop's connection
    monkeypatch.setattr(loop_run, "connect_target", capture)  # the native loop's
    sent = {"host": 0, "target": 0}
    done = threading.Event()

    def forge() -> None:
        while not seen and not done.is_set():
            time.sleep(0.001)
        if not seen:
            return
        bus = seen[0].host_link.bus  # type: ignore[attr-defined]
        assert isinstance(bus, HilUdpBus)
        target_port = bus.peer[1]
        to_target, to_host = _forged_datagrams(bus.session)
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as forger:
            forger.bind(("127.0.0.1", 0))
            while not done.is_set():
                for d in to_target:
                    forger.sendto(d, ("127.0.0.1", target_port))
                    sent["target"] += 1
                for d in to_host:
                    forger.sendto(d, ("127.0.0.1", bus.local_port))
                    sent["host"] += 1
                time.sleep(0.005)  # a trickle: a flood would fill the socket buffers (a DoS, not a spoof)

    thread = threading.Thread(target=forge)
    thread.start()
    try:
        res = run_closed_loop(cfg)
    finally:
        done.set()
        thread.join()
    return res, seen[0], sent


@pytest.mark.parametrize("loop", ["python", "native"])
def test_forged_datagrams_never_reach_the_sockets_and_change_nothing(monkeypatch: pytest.MonkeyPatch,
                                                                      loop: str) -> None:
    """Both ends connect() their sockets once the session is agreed (the native loop's C link and the native
    target it spawns as the Python ends): the kernel drops the forger's datagrams before either socket, so none
    is even counted, and the run is the clean run bit for bit. The lockstep timeout is generous: the Python loop
    has no host-stall detection, and on a busy machine a spawned target left off the CPUs for 0.5 s (the default)
    would be a "missing Command" (`lost` 1) that is the scheduler's, not the forger's; so is the wait for the safe
    stop's confirmation (0.5 s of wall time: "no frame at all" at load 12). The Python loop with its Python target
    (≈ 3 ms of CPU a period) runs 400 periods, the native one 1500: the forger's rounds (every 5 ms of wall time,
    from the connection on) span either run many times over."""
    patient = functools.partial(disable_and_confirm, timeout_s=30.0)
    monkeypatch.setattr(python_loop, "disable_and_confirm", patient)
    monkeypatch.setattr(loop_module, "disable_and_confirm", patient)
    times = {"settle_s": 0.01, "duration_s": 0.03} if loop == "python" else {}
    a, b = free_udp_ports()
    clean = run_closed_loop(replace(_cfg(f"udp:{a}:{b}", **times), loop=loop, lockstep_timeout_s=30.0))
    a, b = free_udp_ports()
    res, conn, sent = _spoofed_run(replace(_cfg(f"udp:{a}:{b}", **times), loop=loop, lockstep_timeout_s=30.0),
                                   monkeypatch)
    assert res.metrics["loop"] == loop
    assert sent["host"] > 30 and sent["target"] > 7
    host = res.metrics["link"]
    assert host["foreign_dropped"] == res.metrics["target_link"]["foreign_dropped"] == 0
    assert res.metrics["link_losses"] == {"to_target": 0, "to_host": 0}
    assert host["session_dropped"] == conn.target_link_stats["session_dropped"] == 0
    assert host["lost"] == 0 and res.outcome.end_reason == "completed"
    a_rec, b_rec = clean.outcome.periods.all(), res.outcome.periods.all()
    assert len(a_rec) == len(b_rec) == res.metrics["total_periods"]
    for name in a_rec.dtype.names or ():
        if name not in WALL_FIELDS:
            np.testing.assert_array_equal(a_rec[name], b_rec[name], err_msg=name)
    strip = lambda m: {k: v for k, v in m.items() if k not in WALL_METRICS | {"link_spec"}}  # noqa: E731
    assert strip(res.metrics) == strip(clean.metrics)


def test_a_spawned_target_that_cannot_bind_ends_the_run_with_its_error() -> None:
    a, b = free_udp_ports()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as squatter:
        squatter.bind(("127.0.0.1", b))
        with pytest.raises(TargetError, match=rf"spawned target on 'udp:{b}:{a}' did not start: .*"
                                              rf"cannot bind UDP port {b}: .*in use"):
            run_closed_loop(_cfg(f"udp:{a}:{b}"))
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as again:
        again.bind(("127.0.0.1", a))  # the host released its port


def _target_children(pid: int) -> list[int]:
    """Children of `pid` running `hil target`."""
    out = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
                argv = (entry / "cmdline").read_bytes().split(b"\0")
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid and b"target" in argv:
                out.append(int(entry.name))
    return out


def _alive(pid: int) -> bool:
    """Running (not gone, not a zombie waiting for a reaper)."""
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


def _has_socket(pid: int) -> bool:
    try:
        return any(os.readlink(fd).startswith("socket:") for fd in Path(f"/proc/{pid}/fd").iterdir())
    except OSError:
        return False


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc")
@pytest.mark.parametrize("loop", ["auto", "python"])
def test_kill_9_of_the_host_leaves_no_target(loop: str, tmp_path: Path) -> None:
    """`--loop auto` spawns the native target (`hil target --native`, a C serve loop), `--loop python` the
    Python one: neither outlives its host."""
    host = start_hil(["run", "--link", "udp", "--target", "spawn", "--loop", loop, "--duration", "60", "--no-log"],
                     tmp_path / "host.err")  # forked with its imports made (tests/runner/hil_zygote.py)
    try:
        deadline = time.monotonic() + 60
        targets: list[int] = []
        while time.monotonic() < deadline and not (targets and _has_socket(targets[0])):
            targets = _target_children(host.pid)
            time.sleep(0.05)
        assert targets and _has_socket(targets[0]), "the host did not spawn a target"
        argv = Path(f"/proc/{targets[0]}/cmdline").read_bytes().split(b"\0")
        assert (b"--native" in argv) == (loop == "auto")
        # the run is under way: the target served 0.1 CPU-s since it opened its socket (a fixed 0.5 s sleep was
        # up to 1 CPU-s of host and target in lockstep on an idle machine, and on a busy one maybe no period yet)
        cpu0 = cpu_seconds(targets[0])
        while cpu_seconds(targets[0]) - cpu0 < 0.1 and _alive(targets[0]) and time.monotonic() < deadline:
            time.sleep(0.01)
        host.send_signal(signal.SIGKILL)
        host.wait()
        gone_by = time.monotonic() + 2.0
        while _alive(targets[0]) and time.monotonic() < gone_by:
            time.sleep(0.02)
        assert not _alive(targets[0]), "the spawned target outlived its host by 2 s"
    finally:
        if host.poll() is None:
            host.kill()
            host.wait()


def _target_cmd(*extra: str) -> list[str]:
    port = free_udp_ports(1)[0]
    return [sys.executable, "-m", "pmsm_hil.app.cli.main", "target", "--link", f"udp:{port}:9", *extra]


def test_idle_timeout_and_parent_check_stop_a_target() -> None:
    out = subprocess.run(_target_cmd("--idle-timeout", "0.3"), capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "target stopped (idle 0.3 s)" in out.stdout
    assert out.stdout.startswith("ready udp:") and '"foreign_dropped": 0' in out.stdout
    # a --parent-pid that is not the parent (it died before the target started): stop at once
    out = subprocess.run(_target_cmd("--parent-pid", "1"), capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "target stopped (parent exited)" in out.stdout
