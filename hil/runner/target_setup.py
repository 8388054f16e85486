"""Connects the runner to a target: in-process sim target, a spawned `hil target` process, or external."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.target_client import TargetClient
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.links import Link, link_kind, open_link, parse_spec


@dataclass(slots=True)
class TargetConnection:
    """The host's link and client, plus whatever runs the target (for closing)."""

    client: TargetClient
    host_link: Link
    target_link: Link | None = None
    process: subprocess.Popen[bytes] | None = None
    inproc_result: Callable[[], object] | None = None
    extra: list[Any] = field(default_factory=list)

    def link_stats(self) -> dict[str, int]:
        """Host link counters plus decoder counters."""
        stats: dict[str, int] = {}
        for source in (self.host_link.stats, self.client.decoder.stats):
            for key, value in vars(source).items() if hasattr(source, "__dict__") else _slots(source):
                if isinstance(value, int):
                    stats[key] = stats.get(key, 0) + value
        return stats

    def close(self) -> None:
        """Close links and stop a spawned target."""
        if self.process is not None:
            self.process.terminate()
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        for link in (self.host_link, self.target_link):
            if link is not None:
                link.close()
        for item in self.extra:
            if isinstance(item, int):
                with contextlib.suppress(OSError):
                    os.close(item)


def _slots(obj: object) -> list[tuple[str, object]]:
    names: list[str] = []
    for cls in type(obj).__mro__:
        names += list(getattr(cls, "__slots__", ()))
    return [(n, getattr(obj, n)) for n in names if hasattr(obj, n)]


def connect_target(cfg: RunConfig, *, silent_after: int | None = None) -> TargetConnection:
    """Open the link(s) and, for in-process or spawned targets, start the target."""
    spec = parse_spec(cfg.link)
    link = link_kind(spec)
    kind = link.auto_target(spec) if cfg.target == "auto" else cfg.target
    codec = FrameCodec(link.profile(spec))
    if kind == "inproc":
        from pmsm_hil.sim_target.target import SimTarget

        target_link = open_link(cfg.link, "target")
        host_link = open_link(cfg.link, "host")
        target = SimTarget(target_link, codec, silent_after=silent_after)
        client = TargetClient(host_link, codec, pump=target.service)
        return TargetConnection(client, host_link, target_link=target_link,
                                inproc_result=lambda: target.last_result, extra=[target])
    if kind == "spawn":
        specs = link.mirror(cfg.link, spec)
        host_link = open_link(specs.host, "host")
        cmd = [sys.executable, "-m", "pmsm_hil.hil.cli.main", "target", "--link", specs.target, "--role", "target"]
        proc = subprocess.Popen(cmd, env=dict(os.environ), stdout=subprocess.DEVNULL)
        client = TargetClient(host_link, codec)
        conn = TargetConnection(client, host_link, process=proc)
        conn.extra.extend(specs.keep_open)
        return conn
    host_link = open_link(cfg.link, "host")
    return TargetConnection(TargetClient(host_link, codec), host_link)
