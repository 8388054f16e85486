"""`hil bench link` runs and reports plausible numbers (small counts); the one speed comparison is `timing`."""

from __future__ import annotations

import argparse
import json
from typing import Any

import pytest

from pmsm_hil.app.cli import bench_link
from pmsm_hil.app.cli.main import main


def _bench_link_json(capsys: pytest.CaptureFixture[str], *argv: str) -> dict[str, Any]:
    p = argparse.ArgumentParser()
    bench_link.add_parser(p.add_subparsers())
    args = p.parse_args(["link", *argv, "--json"])
    assert args.func(args) == 0
    out: dict[str, Any] = json.loads(capsys.readouterr().out)
    return out


def test_bench_link_json(capsys: pytest.CaptureFixture[str]) -> None:
    d = _bench_link_json(capsys, "--count", "50", "--repeats", "2", "--links", "virtual,udp,serial")
    for profile in ("can", "canfd"):
        costs = d["codec"][profile]
        assert set(costs) == {f"{codec}_{op}_ns_per_frame" for codec in ("python", "cantools")
                              for op in ("encode", "decode")}
        assert all(v > 0 for v in costs.values())
    assert set(d["round_trip"]) == {"virtual (one thread)", "udp (peer process)", "serial pty (peer process)"}
    assert all(0 < r["median_us"] <= r["p99_us"] for r in d["round_trip"].values())


@pytest.mark.timing  # compares two codecs' measured ns/frame: a burner preempting one side's repeats flips it
def test_bench_link_our_encoder_beats_cantools(capsys: pytest.CaptureFixture[str]) -> None:
    d = _bench_link_json(capsys, "--count", "200", "--repeats", "5", "--links", "virtual")
    for profile in ("can", "canfd"):
        costs = d["codec"][profile]
        assert costs["python_encode_ns_per_frame"] < costs["cantools_encode_ns_per_frame"], (profile, costs)


@pytest.mark.parametrize(("argv", "needle"), [
    (["--links", "carrier-pigeon"], "--links: unknown link(s) carrier-pigeon"),
    (["--count", "0"], "--count/--repeats must be ≥ 1"),
])
def test_bench_link_bad_args(capsys: pytest.CaptureFixture[str], argv: list[str], needle: str) -> None:
    assert main(["bench", "link", *argv]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith(f"hil: error: {needle}") and len(err.splitlines()) == 1
