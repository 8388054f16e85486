"""Command-line glue for the live dashboard: `--rerun`, `--rerun-save FILE.rrd`, `--rerun-serve` options
and the session around a run (start the dashboard process, print the URL, keep serving until Ctrl-C)."""

from __future__ import annotations

import argparse
import signal
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pmsm_hil.dashboards.recording import RerunTargets

if TYPE_CHECKING:
    import numpy as np


def add_rerun_arguments(p: argparse.ArgumentParser) -> None:
    """Register the live-dashboard options on a subcommand parser."""
    g = p.add_argument_group("live dashboard (Rerun)")
    g.add_argument("--rerun", action="store_true",
                   help="stream to a native Rerun viewer, spawned (needs a display; the viewer stays open)")
    g.add_argument("--rerun-viewer-port", type=int, default=0, metavar="PORT",
                   help="port of the spawned viewer (default 0: a free port; a viewer already listening on PORT "
                        "is reused, so one viewer can collect several runs)")
    g.add_argument("--rerun-save", type=Path, metavar="FILE.rrd", help="write the dashboard recording to FILE.rrd")
    g.add_argument("--rerun-serve", action="store_true",
                   help="serve the dashboard over gRPC with the bundled web viewer (prints the URL; "
                        "keeps serving after the run until Ctrl-C)")
    g.add_argument("--rerun-bind", default="127.0.0.1", metavar="ADDR",
                   help="interface of the served data (gRPC) port (default 127.0.0.1: this machine only; "
                        "0.0.0.0 opens it to the network)")
    g.add_argument("--rerun-web-port", type=int, default=9090, metavar="PORT", help="web viewer port (default 9090)")
    g.add_argument("--rerun-grpc-port", type=int, default=9876, metavar="PORT", help="gRPC port (default 9876)")


def rerun_targets(args: argparse.Namespace) -> RerunTargets:
    """The destinations selected on the command line (none selected: `.any()` is False)."""
    return RerunTargets(spawn=bool(getattr(args, "rerun", False)), save=getattr(args, "rerun_save", None),
                        serve=bool(getattr(args, "rerun_serve", False)),
                        grpc_port=int(getattr(args, "rerun_grpc_port", 9876)),
                        web_port=int(getattr(args, "rerun_web_port", 9090)),
                        bind=str(getattr(args, "rerun_bind", "127.0.0.1")),
                        viewer_port=int(getattr(args, "rerun_viewer_port", 0)))


def hold_serving(url: str) -> None:
    """Keep serving until Ctrl-C or SIGTERM."""
    def on_term(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, on_term)
    print(f"rerun: serving the dashboard at {url} — Ctrl-C to stop", flush=True)
    try:
        while True:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)


@contextmanager
def live_dashboard(args: argparse.Namespace, cfg: Any) -> Iterator[Callable[[np.ndarray], None] | None]:
    """Yields the block consumer for `run_closed_loop(live=...)`, or None when no --rerun option is given.

    `cfg` is the RunConfig (its motor gives Vdc, its machine descriptor the phase count)."""
    targets = rerun_targets(args)
    if not targets.any():
        yield None
        return
    from pmsm_hil.dashboards.live import LiveRerun
    from pmsm_hil.dashboards.recording import check_display

    if targets.spawn:
        check_display()  # here, in one line, rather than from the dashboard process
    phases = cfg.machine.phases
    name = f"{cfg.motor.name} {cfg.controller} {cfg.scenario.name}"
    live = LiveRerun(targets, vdc=cfg.motor.vdc, ts_s=cfg.ts_s, phases=phases, name=name)
    try:
        if live.url is not None:
            print(f"rerun: web viewer at {live.url}", flush=True)
        yield live.submit_periods
        live.flush()
        if targets.save is not None:
            print(f"rerun: recording saved to {targets.save}", file=sys.stderr)
        if live.url is not None:
            hold_serving(live.url)
    finally:
        live.close()
