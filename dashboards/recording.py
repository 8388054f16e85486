"""Where a dashboard recording goes: native viewer (spawn), .rrd file, and/or gRPC + bundled web viewer."""

from __future__ import annotations

import socket
import urllib.parse
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pmsm_hil.dashboards.entities import APPLICATION_ID
from pmsm_hil.dashboards.errors import RerunUnavailableError


@dataclass(frozen=True)
class RerunTargets:
    """`spawn`: start the native viewer; `save`: write this .rrd; `serve`: host gRPC (`grpc_port`) and the
    web viewer (`web_port`, HTTP). Port 0 picks a free port. `bind`: interface of the served ports."""

    spawn: bool = False
    save: Path | None = None
    serve: bool = False
    grpc_port: int = 9876
    web_port: int = 9090
    bind: str = "0.0.0.0"  # the web viewer is often opened from another machine

    def any(self) -> bool:
        """True if at least one destination is selected."""
        return self.spawn or self.save is not None or self.serve


def free_port() -> int:
    """A TCP port that is free on 127.0.0.1 right now."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


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
            port = free_port()
            rr.spawn(port=port, connect=False, hide_welcome_screen=True)
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
