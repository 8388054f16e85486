"""Connects the runner to a target: in-process sim target, a spawned `hil target` process, or external."""

from __future__ import annotations

import contextlib
import os
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.target_client import TargetClient
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.links import Link, open_link


def link_interface(spec: str) -> str:
    """Interface name of a link SPEC (text before ':' or ',')."""
    return spec.split(",", 1)[0].split(":", 1)[0].strip().lower()


def link_profile(spec: str) -> str:
    """Frame profile for a link: 'canfd' unless the spec says fd=false; real CAN adapters default to
    classic CAN unless fd=true (virtual, UDP and serial links carry FD-sized frames)."""
    opts = {k.strip().lower(): v.strip().lower() for k, _, v in
            (item.partition("=") for item in spec.split(",")[1:])}
    fd = opts.get("fd")
    if fd is not None:
        if fd not in ("true", "false", "1", "0", "yes", "no"):
            raise ParameterError(f"link option fd must be true or false, got {fd!r}")
        return "canfd" if fd in ("true", "1", "yes") else "can"
    return "canfd" if link_interface(spec) in ("virtual", "udp", "hiludp", "serial", "hilserial") else "can"


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


def _spawn_specs(spec: str) -> tuple[str, str, list[int]]:
    """Host and target link specs for a spawned target. ``udp:L:R`` gives the target ``udp:R:L``;
    ``serial:pty`` makes a pseudo-terminal pair: the host takes the master descriptor, the target
    process opens the slave by its path."""
    head, sep, opts = spec.partition(",")
    name, _, channel = head.strip().partition(":")
    if name.lower() == "udp" and channel:
        ports, at, host = channel.partition("@")
        local, _, remote = ports.partition(":")
        return spec, f"udp:{remote}:{local}{at}{host}{sep}{opts}", []
    if head.strip().lower() != "serial:pty":
        return spec, spec, []
    master, slave = os.openpty()
    tail = sep + opts
    # the host link owns the master descriptor; we keep the slave open until the run ends
    return f"serial:fd:{master}{tail}", f"serial:{os.ttyname(slave)}{tail}", [slave]


def connect_target(cfg: RunConfig, *, silent_after: int | None = None) -> TargetConnection:
    """Open the link(s) and, for in-process or spawned targets, start the target."""
    kind = cfg.target
    iface = link_interface(cfg.link)
    if kind == "auto":
        if iface == "virtual":
            kind = "inproc"
        elif cfg.link.split(",", 1)[0].strip().lower() == "serial:pty":
            kind = "spawn"
        else:
            kind = "external"
    codec = FrameCodec(link_profile(cfg.link))  # type: ignore[arg-type]
    if kind == "inproc":
        from pmsm_hil.sim_target.target import SimTarget

        target_link = open_link(cfg.link, "target")
        host_link = open_link(cfg.link, "host")
        target = SimTarget(target_link, codec, silent_after=silent_after)
        client = TargetClient(host_link, codec, pump=target.service)
        return TargetConnection(client, host_link, target_link=target_link,
                                inproc_result=lambda: target.last_result, extra=[target])
    if kind == "spawn":
        host_spec, target_spec, fds = _spawn_specs(cfg.link)
        host_link = open_link(host_spec, "host")
        cmd = [sys.executable, "-m", "pmsm_hil.hil.cli.main", "target", "--link", target_spec, "--role", "target"]
        proc = subprocess.Popen(cmd, env=dict(os.environ), stdout=subprocess.DEVNULL)
        client = TargetClient(host_link, codec)
        conn = TargetConnection(client, host_link, process=proc)
        conn.extra.extend(fds)
        return conn
    host_link = open_link(cfg.link, "host")
    return TargetConnection(TargetClient(host_link, codec), host_link)
