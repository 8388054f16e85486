"""A place leased through labgrid's coordinator with `labgrid-client` (labgrid's own command line): a reservation
that waits its turn (`reserve --wait name=PLACE`: a second lease of one place queues behind the first, leases of
different places proceed at once), the place acquired with the reservation's token, its resources read
(`env`), then released and the reservation cancelled."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path
from types import TracebackType
from typing import Any

from pmsm_hil.bench.errors import BenchError

#: labgrid's default coordinator address (its `LG_COORDINATOR` overrides it)
DEFAULT_COORDINATOR = "127.0.0.1:20408"


def labgrid_client() -> str:
    """The `labgrid-client` beside this Python, else on PATH; BenchError when labgrid is not installed."""
    beside = Path(sys.executable).with_name("labgrid-client")
    found = str(beside) if beside.is_file() else shutil.which("labgrid-client")
    if found is None:
        raise BenchError("labgrid is not installed (pip install 'pmsm-hil[bench]'): no labgrid-client")
    return found


def coordinator_address(explicit: str | None = None) -> str:
    """The coordinator: `explicit`, else `LG_COORDINATOR`, else labgrid's default."""
    return explicit or os.environ.get("LG_COORDINATOR") or DEFAULT_COORDINATOR


class PlaceLease:
    """`with PlaceLease("bench-a") as lease:` waits for the place, acquires it, and releases it on leaving;
    `lease.resources` holds the place's resources as `labgrid-client env` gives them (class -> parameters)."""

    def __init__(self, place: str, coordinator: str | None = None) -> None:
        self.place = place
        self.coordinator = coordinator_address(coordinator)
        self.token: str | None = None
        self.acquired = False
        self.resources: dict[str, dict[str, Any]] = {}

    def _client(self, *args: str, timeout: float | None = 120.0) -> str:
        cmd = [labgrid_client(), "-x", self.coordinator, *args]
        try:
            done = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=False)
        except subprocess.TimeoutExpired:
            raise BenchError(f"bench {self.place}: labgrid-client {' '.join(args)} took more than {timeout:g} s "
                             f"(coordinator {self.coordinator})") from None
        if done.returncode != 0:
            last = (done.stderr.strip().splitlines() or ["no message"])[-1]
            raise BenchError(f"bench {self.place}: labgrid-client {' '.join(args)} failed: {last}")
        return done.stdout

    def __enter__(self) -> PlaceLease:
        places = self._client("places").split()
        if self.place not in places:
            raise BenchError(f"bench {self.place}: no such place on the coordinator {self.coordinator} (places: "
                             f"{', '.join(places) or 'none'})")
        out = self._client("reserve", "--wait", "--shell", f"name={self.place}", timeout=None)
        found = re.search(r"LG_TOKEN=(\w+)", out)
        if found is None:
            raise BenchError(f"bench {self.place}: no reservation token from labgrid-client reserve: {out.strip()!r}")
        self.token = found.group(1)
        try:
            self._client("-p", f"+{self.token}", "acquire")
            self.acquired = True
            self.resources = parse_env(self._client("-p", f"+{self.token}", "env"))
        except BaseException:
            self.release()
            raise
        return self

    def __exit__(self, kind: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None) -> None:
        self.release()

    def release(self) -> None:
        """Release the place and cancel the reservation (both at most once; errors only when nothing was freed)."""
        token, self.token = self.token, None
        if token is None:
            return
        try:
            if self.acquired:
                self.acquired = False
                self._client("-p", f"+{token}", "release")
        finally:
            self._client("cancel-reservation", token)


def parse_env(text: str) -> dict[str, dict[str, Any]]:
    """The resources of a `labgrid-client env` output (YAML `targets: {NAME: {resources: [...]}}`) as class ->
    parameters (the first of each class)."""
    import yaml

    data = yaml.safe_load(text) or {}
    found: dict[str, dict[str, Any]] = {}
    for target in (data.get("targets") or {}).values():
        for entry in (target or {}).get("resources") or []:
            for cls, params in entry.items():
                found.setdefault(str(cls), dict(params or {}))
    return found
