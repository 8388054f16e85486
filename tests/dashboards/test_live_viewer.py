"""The native Rerun viewer: `hil run --rerun` spawns the wheel's viewer with the recording (under Xvfb with a
software Vulkan driver), `hil replay --rerun` reaches it too, finishes and honours Ctrl-C; `--rerun-serve`
binds loopback unless `--rerun-bind` opens it."""

from __future__ import annotations

import argparse
import contextlib
import glob
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.dashboards.entities import APPLICATION_ID
from pmsm_hil.dashboards.recording import RerunTargets, free_port, open_recording, viewer_executable

HIL = Path(sys.executable).parent / "hil"


def _end_viewer(port: int) -> None:
    """Stop the viewer listening on `port` (found by its command line) and remove its log."""
    for pid in _viewer_pids(port):
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGTERM)
    (Path(tempfile.gettempdir()) / f"hil-rerun-viewer-{port}.log").unlink(missing_ok=True)


def _viewer_pids(port: int) -> list[int]:
    """Processes of the viewer listening on `port` (its command line names the port)."""
    pids = []
    for proc in Path("/proc").iterdir():
        if proc.name.isdigit():
            with contextlib.suppress(OSError):
                if f"--port={port}" in (proc / "cmdline").read_bytes().decode(errors="replace"):
                    pids.append(int(proc.name))
    return pids


@contextlib.contextmanager
def _virtual_display() -> Iterator[str]:
    """An Xvfb display for the viewer; skips with the reason when Xvfb or a Vulkan driver is missing."""
    if shutil.which("Xvfb") is None:
        pytest.skip("no Xvfb for the native Rerun viewer (apt install xvfb; .ci/run installs it)")
    if not glob.glob("/usr/share/vulkan/icd.d/*.json"):
        pytest.skip("no Vulkan driver for the native Rerun viewer (apt install mesa-vulkan-drivers)")
    read, write = os.pipe()
    xvfb = subprocess.Popen(["Xvfb", "-displayfd", str(write), "-screen", "0", "1280x1024x24", "-nolisten", "tcp"],
                            pass_fds=(write,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(write)
    try:
        with os.fdopen(read) as fh:
            number = fh.readline().strip()
        assert number.isdigit(), "Xvfb did not report its display"
        yield f":{number}"
    finally:
        xvfb.terminate()
        xvfb.wait(10)


def _recordings(port: int, want: int, timeout_s: float = 30.0) -> list[Any]:
    """The viewer's recordings of our application once `want` of them have their `time` timeline."""
    from rerun.experimental import ViewerClient

    client = ViewerClient.connect(f"rerun+http://127.0.0.1:{port}/proxy")
    deadline = time.monotonic() + timeout_s
    while True:
        ours = [r for r in client.get_state().recordings if f":{APPLICATION_ID}:" in r.store_id
                and any(t.name == "time" for t in r.timelines)]
        if len(ours) >= want or time.monotonic() > deadline:
            return [(r, client.get_recording_schema(r.store_id, paths_only=True)) for r in ours]
        time.sleep(0.2)


def test_live_run_and_replay_reach_the_spawned_viewer(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                      capsys: pytest.CaptureFixture[str]) -> None:
    with _virtual_display() as display:
        monkeypatch.setenv("DISPLAY", display)
        port = free_port()
        try:
            t0 = time.monotonic()
            rc = main(["run", "--rerun", "--rerun-viewer-port", str(port), "--duration", "0.05", "--settle", "0",
                       "--out", str(tmp_path / "run")])
            live_s = time.monotonic() - t0
            assert rc == 0 and _viewer_pids(port), "the viewer was not started"
            assert live_s < 25.0  # it used to wait 30 s for a flush to a viewer that never started, then exit 2
            (live, schema), = _recordings(port, 1)
            time_line = next(t for t in live.timelines if t.name == "time")
            assert time_line.end == 49_900_000  # 500 periods of 100 µs: the last period start, ns
            paths = {e.entity_path for e in schema.entities}
            assert {"/torque/actual", "/currents/i_a", "/speed/actual", "/ab/selected"} <= paths
            # the recorded run into the same viewer (reused on its port): a second recording, same rows
            t0 = time.monotonic()
            assert main(["replay", str(tmp_path / "run" / "run.mcap"), "--rerun",
                         "--rerun-viewer-port", str(port)]) == 0
            assert time.monotonic() - t0 < 25.0
            recs = _recordings(port, 2)
            assert len(recs) == 2
            assert all(next(t for t in r.timelines if t.name == "time").end == 49_900_000 for r, _ in recs)
        finally:
            _end_viewer(port)
    assert "replayed 500 periods" in capsys.readouterr().out


#: `timing`: the Ctrl-C must come while the replay waits; beside load 12 its own 20 s flush bound ended it first
@pytest.mark.timing
def test_replay_to_a_viewer_that_cannot_start_honours_ctrl_c(tmp_path: Path) -> None:
    """No X server behind DISPLAY: the viewer dies, the replay waits for it in short flush steps, and a
    Ctrl-C ends it (it used to hang in one native flush for more than 10 minutes, deaf to Ctrl-C)."""
    run = tmp_path / "run"
    assert main(["run", "--duration", "0.05", "--settle", "0", "--out", str(run), "--quiet"]) == 0  # the log to replay
    port = free_port()
    log = Path(tempfile.gettempdir()) / f"hil-rerun-viewer-{port}.log"
    env = {**os.environ, "DISPLAY": ":987"}  # no such X server
    proc = subprocess.Popen([str(HIL), "replay", str(run / "run.mcap"), "--rerun", "--rerun-viewer-port", str(port)],
                            env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        # rerun waits ≈ 6 s for a viewer to bind before giving up; the `hil` process's start-up before it took
        # > 30 s of wall time beside load 10: the bound is for a hang (it used to be > 10 min), not a speed
        deadline = time.monotonic() + 300.0
        while not (log.is_file() and "did not bind" in log.read_text(errors="replace")):
            ended = proc.poll()
            said = proc.stderr.read() if ended is not None and proc.stderr else ""
            assert time.monotonic() < deadline and ended is None, f"spawn did not return (exit {ended}: {said})"
            time.sleep(0.2)
        time.sleep(1.0)  # now streaming or waiting in the flush loop
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)  # rerun's own exit waits ≤ 5 s for the connection (idle machine)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        _end_viewer(port)
    assert proc.returncode == 130
    assert "hil: interrupted" in err and "Traceback" not in err


def test_spawn_call_receives_the_recording(monkeypatch: pytest.MonkeyPatch) -> None:
    """Without `recording=` rerun found no global recording and ignored the spawn ("Rerun is disabled")."""
    import rerun as rr

    calls: list[dict[str, Any]] = []
    server = rr.RecordingStream("stand-in viewer")
    port = free_port()

    def fake_spawn(**kwargs: Any) -> None:
        calls.append(kwargs)
        rr.serve_grpc(grpc_port=port, recording=server)  # something for the recording's gRPC sink to reach

    monkeypatch.setattr(rr, "spawn", fake_spawn)
    monkeypatch.setenv("DISPLAY", ":0")
    rec, url = open_recording(RerunTargets(spawn=True, viewer_port=port), None)
    try:
        assert url is None and len(calls) == 1
        assert calls[0]["recording"] is rec and calls[0]["port"] == port and calls[0]["connect"] is False
        assert calls[0]["executable_path"] == viewer_executable() and Path(calls[0]["executable_path"]).is_file()
    finally:
        rec.disconnect()
        server.disconnect()
        _end_viewer(port)


def test_no_display_is_a_one_line_error(monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    if not sys.platform.startswith("linux"):
        pytest.skip("the display check is for Linux")
    assert main(["run", "--rerun", "--no-log", "--duration", "0.01", "--settle", "0"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("hil: error: --rerun: no display") and len(err.splitlines()) == 1


def _listening_hosts(port: int) -> set[str]:
    """Local addresses (hex, /proc/net/tcp form) listening on `port`."""
    hosts = set()
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        local, state = line.split()[1], line.split()[3]
        host, hex_port = local.split(":")
        if int(hex_port, 16) == port and state == "0A":
            hosts.add(host)
    return hosts


@pytest.mark.parametrize(("bind", "expected"), [(None, "0100007F"), ("0.0.0.0", "00000000")])
def test_serve_binds_loopback_unless_opened(bind: str | None, expected: str) -> None:
    from pmsm_hil.dashboards.cli_live import add_rerun_arguments, rerun_targets
    from pmsm_hil.dashboards.live import LiveRerun

    p = argparse.ArgumentParser()
    add_rerun_arguments(p)
    grpc, web = free_port(), free_port()
    argv = ["--rerun-serve", "--rerun-grpc-port", str(grpc), "--rerun-web-port", str(web)]
    targets = rerun_targets(p.parse_args(argv + (["--rerun-bind", bind] if bind else [])))
    with LiveRerun(targets, vdc=400.0, ts_s=1e-4) as live:
        assert live.url is not None and live.url.startswith(f"http://127.0.0.1:{web}/")
        assert _listening_hosts(grpc) == {expected}
