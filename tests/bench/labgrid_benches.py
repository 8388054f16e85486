"""Simulated benches behind a labgrid coordinator and exporter on loopback, started and stopped by the tests: each
place's board is a `hil target` process (started by the place's flash) behind a UDP link on free ports."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

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

    def client(self, *args: str) -> str:
        """Run `labgrid-client` against the coordinator; its output."""
        done = subprocess.run([str(BIN / "labgrid-client"), "-x", self.address, *args], capture_output=True,
                              text=True, timeout=120, check=False)
        assert done.returncode == 0, (args, done.stdout, done.stderr)
        return done.stdout

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
        while True:  # its port first (a connect is cheap; each labgrid-client is ~1 CPU-s of Python start-up)
            try:
                socket.create_connection((host, int(port)), timeout=5).close()
            except OSError:
                assert time.monotonic() < deadline, (self.folder / "coordinator.log").read_text()
                time.sleep(0.2)
                continue
            if subprocess.run([str(BIN / "labgrid-client"), "-x", self.address, "places"], capture_output=True,
                              timeout=60, check=False).returncode == 0:
                break
            assert time.monotonic() < deadline, (self.folder / "coordinator.log").read_text()
            time.sleep(0.5)
        self._start(str(BIN / "labgrid-exporter"), "-c", self.address, "-n", "sim", "--hostname", "127.0.0.1",
                    str(self.folder / "exporter.yaml"), log="exporter.log")
        for name in self.links:
            self.client("-p", name, "create")
            self.client("-p", name, "add-match", f"sim/{name}/*")
        while True:  # one listing for every place
            listed = self.client("resources")
            if all(f"sim/{name}/HilLink" in listed for name in self.links):
                break
            assert time.monotonic() < deadline, (self.folder / "exporter.log").read_text()
            time.sleep(0.5)

    def stop(self) -> None:
        """End the exporter and the coordinator."""
        for proc in reversed(self.procs):
            if proc.poll() is None:
                os.killpg(proc.pid, signal.SIGTERM)
                try:
                    proc.wait(10)
                except subprocess.TimeoutExpired:
                    os.killpg(proc.pid, signal.SIGKILL)
                    proc.wait()
