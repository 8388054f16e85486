"""A bench for the length of a `with`: the place leased through labgrid's coordinator (`PlaceLease`: waits its turn),
its labgrid target made from an environment (the user's `--lg-env` file, or one made for the place: a RemotePlace
with this package's drivers and strategy), brought to "ready" by `HilBenchStrategy` (flash, reset, heartbeat),
and on leaving switched off and released, whatever happened inside."""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from pmsm_hil.bench.errors import BenchError
from pmsm_hil.bench.place import PlaceLease

#: the labgrid environment made for a place named on the command line (`hil run --place NAME`)
PLACE_ENV = """\
targets:
  main:
    resources:
      RemotePlace:
        name: {place}
    drivers:
      - HilLinkDriver: {{}}
      - SimBoardDriver: {{}}
      - HilBenchStrategy: {{}}
options:
  coordinator_address: "{coordinator}"
imports:
  - pmsm_hil.bench.labgrid_parts
"""


@dataclass
class Bench:
    """A leased bench that answered: its place, its link (`hil run --link` spec), its labgrid target."""

    place: str
    link: str
    target: Any
    heartbeat_s: float | None


def env_places(env_file: str | Path) -> list[str]:
    """The RemotePlace names of a labgrid environment file (the places its targets need)."""
    import yaml

    data = yaml.safe_load(Path(env_file).read_text(encoding="utf-8")) or {}
    names: list[str] = []
    for target in (data.get("targets") or {}).values():
        resources = (target or {}).get("resources") or {}
        entries = resources if isinstance(resources, list) else [resources]
        for entry in entries:
            place = (entry or {}).get("RemotePlace")
            if isinstance(place, dict) and "name" in place:
                names.append(str(place["name"]))
    return names


def env_coordinator(env_file: str | Path) -> str | None:
    """The coordinator address of a labgrid environment file (`options: coordinator_address`), or None."""
    import yaml

    data = yaml.safe_load(Path(env_file).read_text(encoding="utf-8")) or {}
    address = (data.get("options") or {}).get("coordinator_address")
    return None if address is None else str(address)


@contextlib.contextmanager
def open_bench(place: str, *, coordinator: str | None = None, env_file: str | Path | None = None) -> Iterator[Bench]:
    """Lease `place`, bring it to ready with the environment `env_file` (None: one made for the place) and yield
    the `Bench`; on leaving, the board is switched off and the place released. The coordinator: `coordinator`,
    else the environment file's, else `LG_COORDINATOR`, else labgrid's default."""
    import labgrid

    import pmsm_hil.bench.labgrid_parts  # noqa: F401 (registers the resources, drivers and strategy)

    if coordinator is None and env_file is not None:
        coordinator = env_coordinator(env_file)
    with PlaceLease(place, coordinator) as lease, tempfile.TemporaryDirectory(prefix="hil-bench-") as tmp:
        if env_file is None:
            env_file = Path(tmp) / "env.yaml"
            env_file.write_text(PLACE_ENV.format(place=place, coordinator=lease.coordinator), encoding="utf-8")
        env = labgrid.Environment(config_file=str(env_file))
        env.config.set_option("coordinator_address", lease.coordinator)
        target = env.get_target("main")
        if target is None:
            raise BenchError(f"bench {place}: the labgrid environment {env_file} has no target 'main'")
        try:
            strategy = target.get_driver("HilBenchStrategy")
            strategy.transition("ready")
            yield Bench(place, strategy.link.spec, target, strategy.heartbeat_s)
        finally:
            with contextlib.suppress(Exception):
                target.get_driver("HilBenchStrategy").transition("off")
            target.cleanup()
