"""`hil bench link` runs and reports plausible numbers (small counts; timings not asserted tightly)."""

from __future__ import annotations

import argparse
import json

import pytest
from pmsm_hil.app.cli import bench_link
from pmsm_hil.app.cli.main import main


def test_bench_link_json(capsys: pytest.CaptureFixture[str]) -> None:
    p = argparse.ArgumentParser()
    bench_link.add_parser(p.add_subparsers())
    args = p.parse_args(["link", "--count", "50", "--repeats", "2", "--links", "virtual,udp,serial", "--json"])
    assert args.func(args) == 0
    d = json.loads(capsys.readouterr().out)
    for profile in ("can", "canfd"):
        costs = d["codec"][profile]
        assert all(v > 0 for v in costs.values())
        assert costs["python_encode_ns_per_frame"] < costs["cantools_encode_ns_per_frame"]
    assert set(d["round_trip"]) == {"virtual (one thread)", "udp (peer process)", "serial pty (peer process)"}
    assert all(0 < r["median_us"] <= r["p99_us"] for r in d["round_trip"].values())


@pytest.mark.parametrize(("argv", "needle"), [
    (["--links", "carrier-pigeon"], "--links: unknown link(s) carrier-pigeon"),
    (["--count", "0"], "--count/--repeats must be ≥ 1"),
])
def test_bench_link_bad_args(capsys: pytest.CaptureFixture[str], argv: list[str], needle: str) -> None:
    assert main(["bench", "link", *argv]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith(f"hil: error: {needle}") and len(err.splitlines()) == 1
