"""Simulated benches behind a labgrid coordinator and exporter on loopback, started and stopped by the tests: each
place's board is a `hil target` process (started by the place's flash) behind a UDP link on free ports. The places
are made and read through labgrid's client session in this process (no `labgrid-client` process per step)."""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

BIN = Path(sys.executable).parent


def free_port(kind: int = socket.SOCK_STREAM) -> int:
    """A free loopback port of `kind`."""
    with socket.socket(socket.AF_INET, kind) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Benches:
    """A coordinator and an exporter on loopback exporting `places` (name -> host link, board link)."""

    def __init__(self, folder: Path, places: tuple[str, ...]) -> None:
        self.folder = folder
        self.address = f"127.0.0.1:{free_port()}"
        self.links: dict[str, tuple[str, str]] = {}
        for name in places:
            host, board = free_port(socket.SOCK_DGRAM), free_port(socket.SOCK_DGRAM)
            self.links[name] = (f"udp:{host}:{board}@127.0.0.1", f"udp:{board}:{host}@127.0.0.1")
        self.procs: list[subprocess.Popen[bytes]] = []
        self.session: Any = None

    def _call(self, coro: Any) -> Any:
        import asyncio

        return self.session.loop.run_until_complete(asyncio.wait_for(coro, 120))

    def held(self) -> list[str]:
        """The places acquired now (as the coordinator tells them)."""
        self._call(self.session.sync_with_coordinator())
        return [name for name, place in self.session.places.items() if place.acquired]

    def _start(self, *cmd: str, log: str) -> None:
        with (self.folder / log).open("wb") as out:
            self.procs.append(subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT, cwd=self.folder,
                                               start_new_session=True))

    def start(self) -> None:
        """Coordinator, exporter, places; returns when the places' resources are matched."""
        self._start(str(BIN / "labgrid-coordinator"), "-l", self.address, log="coordinator.log")
        config = "".join(f"{name}:\n  HilLink:\n    spec: '{host}'\n  HilSimBoard:\n    target_link: '{board}'\n"
                         for name, (host, board) in self.links.items())
        (self.folder / "exporter.yaml").write_text(config, encoding="utf-8")
        deadline = time.monotonic() + 90
        host, port = self.address.split(":")
        while True:  # its port first (a connect is cheap), then the client session
            try:
                socket.create_connection((host, int(port)), timeout=5).close()
            except OSError:
                assert time.monotonic() < deadline, (self.folder / "coordinator.log").read_text()
                time.sleep(0.2)
                continue
            break
        from labgrid.remote.client import start_session
        from labgrid.remote.generated import labgrid_coordinator_pb2 as pb2

        self.session = start_session(self.address)
        self._start(str(BIN / "labgrid-exporter"), "-c", self.address, "-n", "sim", "--hostname", "127.0.0.1",
                    str(self.folder / "exporter.yaml"), log="exporter.log")
        for name in self.links:
            self._call(self.session.stub.AddPlace(pb2.AddPlaceRequest(name=name)))
            self._call(self.session.stub.AddPlaceMatch(pb2.AddPlaceMatchRequest(placename=name,
                                                                                pattern=f"sim/{name}/*")))
        while True:  # every place's resources exported
            self._call(self.session.sync_with_coordinator())
            exported = self.session.resources.get("sim", {})
            if all("HilLink" in exported.get(name, {}) for name in self.links):
                break
            assert time.monotonic() < deadline, (self.folder / "exporter.log").read_text()
            time.sleep(0.5)

    def stop(self) -> None:
        """End the client session, the exporter and the coordinator."""
        if self.session is not None:
            session, self.session = self.session, None
            for step in (session.stop, session.close):
                with contextlib.suppress(Exception):  # the coordinator may be gone already
                    session.loop.run_until_complete(step())
        for proc in reversed(self.procs):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait()
