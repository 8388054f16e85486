"""Reading a place's resources and an environment's places without a coordinator."""

from __future__ import annotations

from pathlib import Path

import pytest

from pmsm_hil.bench.errors import BenchError
from pmsm_hil.bench.place import PlaceLease, parse_env
from pmsm_hil.bench.session import env_coordinator, env_places
from pmsm_hil.bench.sim_board import SimBoard
from pmsm_hil.errors import HilError


def test_parse_env_gives_each_resource_class_its_parameters() -> None:
    text = ("targets:\n  main:\n    resources:\n    - HilLink:\n        spec: udp:1:2@127.0.0.1\n"
            "    - HilSimBoard:\n        target_link: udp:2:1@127.0.0.1\n")
    assert parse_env(text) == {"HilLink": {"spec": "udp:1:2@127.0.0.1"},
                               "HilSimBoard": {"target_link": "udp:2:1@127.0.0.1"}}


def test_env_places_and_coordinator_come_from_the_environment_file(tmp_path: Path) -> None:
    env = tmp_path / "env.yaml"
    env.write_text("targets:\n  main:\n    resources:\n      RemotePlace: {name: drive-bench-1}\n"
                   "options:\n  coordinator_address: '10.0.0.5:20408'\n", encoding="utf-8")
    assert env_places(env) == ["drive-bench-1"]
    assert env_coordinator(env) == "10.0.0.5:20408"


def test_an_unreachable_coordinator_is_one_error_naming_the_bench() -> None:
    pytest.importorskip("labgrid", reason="labgrid is not installed (the `bench` extra)")
    with pytest.raises(BenchError, match="bench nowhere: connecting to the coordinator failed") as caught:
        PlaceLease("nowhere", coordinator="127.0.0.1:9").__enter__()
    assert isinstance(caught.value, HilError)


def test_a_simulated_board_refuses_a_missing_image(tmp_path: Path) -> None:
    with pytest.raises(BenchError, match=r"board b1: image .*nope.so is not a file"):
        SimBoard("udp:1:2@127.0.0.1", name="b1").flash(tmp_path / "nope.so")


def test_the_example_bench_files_name_their_places_and_valid_links() -> None:
    import yaml

    from pmsm_hil.protocol.links.spec import parse_spec

    examples = Path(__file__).resolve().parents[2] / "examples" / "bench"
    assert env_places(examples / "env-sim.yaml") == ["sim-a"]
    assert env_places(examples / "env-nucleo.yaml") == ["drive-bench-1"]
    for name in ("exporter-sim.yaml", "exporter-nucleo.yaml"):
        places = yaml.safe_load((examples / name).read_text(encoding="utf-8"))
        for resources in places.values():
            parse_spec(resources["HilLink"]["spec"])
            if "HilSimBoard" in resources:
                parse_spec(resources["HilSimBoard"]["target_link"])
