"""Where a dashboard recording goes: native viewer (spawn), .rrd file, and/or gRPC + bundled web viewer."""

from __future__ import annotations

import contextlib
import os
import socket
import sys
import tempfile
import time
import urllib.parse
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pmsm_hil.dashboards.entities import APPLICATION_ID
from pmsm_hil.dashboards.errors import DashboardError, RerunUnavailableError


@dataclass(frozen=True)
class RerunTargets:
    """`spawn`: start the native viewer (listening on `viewer_port`; 0: a free port; a viewer already
    listening there is reused); `save`: write this .rrd; `serve`: host gRPC (`grpc_port`) and the web viewer
    (`web_port`, HTTP). Port 0 picks a free port. `bind`: interface of the served gRPC (data) port —
    loopback unless opened on purpose (`--rerun-bind 0.0.0.0`)."""

    spawn: bool = False
    save: Path | None = None
    serve: bool = False
    grpc_port: int = 9876
    web_port: int = 9090
    bind: str = "127.0.0.1"
    viewer_port: int = 0

    def any(self) -> bool:
        """True if at least one destination is selected."""
        return self.spawn or self.save is not None or self.serve


def free_port() -> int:
    """A TCP port that is free on 127.0.0.1 right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def viewer_executable() -> str | None:
    """The `rerun` viewer installed beside this Python (the rerun-sdk wheel's; found even when the venv's
    bin folder is not on PATH), else None (rerun then searches PATH)."""
    exe = Path(sys.executable).parent / "rerun"
    return str(exe) if exe.is_file() else None


def check_display() -> None:
    """RerunUnavailableError if the native viewer cannot open a window here (Linux without X11/Wayland)."""
    if sys.platform.startswith("linux") and not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        raise RerunUnavailableError("--rerun: no display (DISPLAY and WAYLAND_DISPLAY are unset) for the native "
                                    "viewer; use --rerun-save FILE.rrd or --rerun-serve")


def _no_inheritance() -> None:
    """Mark every descriptor above stderr close-on-exec: the viewer must not inherit our pipes (the
    multiprocessing resource tracker's, the dashboard's), which would keep their readers, and with
    them the command's stdout, alive for as long as the viewer runs."""
    for folder in ("/proc/self/fd", "/dev/fd"):
        try:
            fds = [int(name) for name in os.listdir(folder)]
        except (OSError, ValueError):
            continue
        for fd in fds:
            if fd > 2:
                with contextlib.suppress(OSError):
                    os.set_inheritable(fd, False)
        return


@contextlib.contextmanager
def viewer_output(port: int) -> Iterator[Path]:
    """Point this process's stdout/stderr at the viewer's log file while the viewer is spawned: the viewer
    inherits them and outlives the command, and must not hold the command's pipes (`hil run --rerun | tee`)
    open after the command has ended."""
    log = Path(tempfile.gettempdir()) / f"hil-rerun-viewer-{port}.log"
    sys.stdout.flush()
    sys.stderr.flush()
    _no_inheritance()
    fd = os.open(log, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    saved = (os.dup(1), os.dup(2))
    try:
        os.dup2(fd, 1)
        os.dup2(fd, 2)
        yield log
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for f in (*saved, fd):
            os.close(f)


def flush_recording(rec: Any, timeout_s: float = 20.0, *, step_s: float = 0.25) -> None:
    """`rec.flush()` in short steps, so Ctrl-C is honoured while a viewer takes the data; DashboardError
    naming the destination when it does not take everything within `timeout_s` [s] (viewer closed or gone)."""
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            rec.flush(timeout_sec=step_s)
            return
        except RuntimeError as exc:
            if "timed out" not in str(exc).lower():
                raise DashboardError(f"rerun: {exc}") from None
        if time.monotonic() > deadline:
            raise DashboardError(f"rerun: the viewer did not take the recording within {timeout_s:g} s (closed? a "
                                 f"spawned viewer logs to {tempfile.gettempdir()}/hil-rerun-viewer-PORT.log)")


def web_viewer_url(web_port: int, grpc_uri: str, host: str = "127.0.0.1") -> str:
    """URL that opens the bundled web viewer connected to `grpc_uri`."""
    return f"http://{host}:{web_port}/?url={urllib.parse.quote(grpc_uri, safe='')}"


def open_recording(targets: RerunTargets, blueprint: Any, *, recording_id: str | None = None) -> tuple[Any, str | None]:
    """A RecordingStream sending to `targets` with `blueprint` as default; returns (stream, web URL or None)."""
    try:
        import rerun as rr
    except ImportError as exc:
        raise RerunUnavailableError(f"rerun: the rerun-sdk package is not installed ({exc})") from None
    if not targets.any():
        raise RerunUnavailableError("rerun: no destination (use --rerun, --rerun-save FILE or --rerun-serve)")
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=recording_id)
    sinks: list[Any] = []
    url: str | None = None
    try:
        if targets.save is not None:
            if not targets.save.parent.is_dir():
                raise RerunUnavailableError(f"--rerun-save: directory {targets.save.parent} does not exist")
            sinks.append(rr.FileSink(str(targets.save)))
        if targets.spawn:
            check_display()
            port = targets.viewer_port or free_port()
            # `recording=rec`: without it rerun looks for a global recording, finds none and ignores the call
            with viewer_output(port):
                rr.spawn(port=port, connect=False, hide_welcome_screen=True, recording=rec,
                         executable_path=viewer_executable())
            sinks.append(rr.GrpcSink(f"rerun+http://127.0.0.1:{port}/proxy"))
        server = None
        if targets.serve:
            grpc_port = targets.grpc_port or free_port()
            server = rr.GrpcServerSink(targets.bind, grpc_port)
            sinks.append(server)
        rec.set_sinks(*sinks, default_blueprint=blueprint)
        if server is not None:
            web_port = targets.web_port or free_port()
            grpc_uri = f"rerun+http://127.0.0.1:{server.uri.rsplit(':', 1)[-1]}" if "0.0.0.0" in server.uri \
                else server.uri
            rr.serve_web_viewer(web_port=web_port, open_browser=False, connect_to=grpc_uri)
            url = web_viewer_url(web_port, grpc_uri)
    except RerunUnavailableError:
        raise
    except Exception as exc:  # rerun reports bind/spawn failures with assorted exception types
        raise RerunUnavailableError(f"rerun: cannot open the recording destination ({type(exc).__name__}: {exc})") \
            from None
    return rec, url
