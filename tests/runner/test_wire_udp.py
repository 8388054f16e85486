"""The native loop over UDP (src/pmsm_hil/hil/runner/c/links/loop_udp.c) with the native target it spawns (`hil target
--native`, src/pmsm_hil/hil/runner/c/target_serve.c) gives the records, frames and metrics of the Python loop with the
Python target over the same link, bit for bit (but what the wall clock measures). The killed host:
tests/runner/test_spawn_safety.py."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.runlog.reader import read_frames
from pmsm_hil.hil.runner.run import RunResult, run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.protocol.links.wire_bus import free_udp_ports
from tests.runner.test_loop import SENSORS, _assert_same_frames, _mirrored, _six, _three

#: measured on the wall clock (exec times come from the target's clock; no split or torque reference crosses
#: the link, so those are 0 / NaN in both loops alike and compared)
WALL_FIELDS = {"exec_time_ns"}
WALL_METRICS = {"exec_time_us", "exec_split_us", "exec_time_first_us",
                "total_wall_time_s", "loop_rate_total_hz", "loop_rate_hz",
                "wall_time_s", "realtime_factor", "loop", "loop_note", "command_wait_max_us", "link_spec", "link",
                "safe_stop_wait_ms", "target_link"}
#: the native links' counters of how receives waited (NativeWireLink.waits): the machine's timing
WAIT_COUNTERS = {"blocked", "spin_backoffs", "spin_early_ends"}
#: what the host's scheduling of the spawned target decides: a wait it prolonged past the lockstep timeout is a host
#: stall, counted and warned about (`host stall: ...`), never a finding; the records are the same
HOST_STALL_METRICS = {"host_stalls", "host_stall_s"}


def _pair(cfg: RunConfig, tmp_path: Path | None = None) -> tuple[RunResult, RunResult]:
    """The Python loop + Python target, then the native loop + native target, each spawned on fresh ports, at the
    default lockstep timeout: both loops count the spawned target's own time (a target left off the CPUs on a busy
    machine is a host stall, not a `missing` Command)."""
    runs = []
    for loop in ("python", "native"):
        a, b = free_udp_ports()
        link = cfg.link.replace("udp", f"udp:{a}:{b}", 1)
        out = None if tmp_path is None else tmp_path / loop
        runs.append(run_closed_loop(replace(cfg, link=link, target="spawn", loop=loop, out_dir=out)))
    py, na = runs
    assert py.metrics["loop"] == "python" and na.metrics["loop"] == "native" and na.metrics["loop_note"] is None
    return py, na


def _without_resends(link: dict[str, Any]) -> dict[str, Any]:
    """The link counters less the configuration's resends (`config_resent` ConfigParam frames sent, the
    `config_acks_repeated` ConfigAcks answering them): a target slow to start on a busy machine (the Python target
    in the CI VM) gets a resend after 0.25 s of wall time, the run's frames are the same."""
    out = dict(link)
    resent, repeated = out.pop("config_resent"), out.pop("config_acks_repeated")
    assert isinstance(resent, int) and isinstance(repeated, int) and resent >= 0 and repeated >= 0
    out["frames_tx"] -= resent
    for key in ("frames_rx", "frames", "messages"):
        out[key] -= repeated
    return out


def _comparable(metrics: dict[str, Any]) -> dict[str, Any]:
    """The metrics but those the wall clock or the host's scheduling decides (WALL_METRICS, HOST_STALL_METRICS,
    the host stall's warning)."""
    out = {key: value for key, value in metrics.items() if key not in WALL_METRICS | HOST_STALL_METRICS}
    out["warnings"] = [w for w in metrics["warnings"] if not w.startswith("host stall:")]
    return out


def _assert_same(py: RunResult, na: RunResult) -> None:
    a, b = py.outcome.periods.all(), na.outcome.periods.all()
    assert a.shape == b.shape and a.shape[0] > 0
    for name in a.dtype.names or ():
        if name not in WALL_FIELDS:
            assert a[name].tobytes() == b[name].tobytes(), name
    assert (b["exec_time_ns"][1:] > 0).any()  # the native target measured its steps
    assert py.metrics.keys() == na.metrics.keys()
    py_m, na_m = _comparable(py.metrics), _comparable(na.metrics)
    for key in py_m:
        assert py_m[key] == na_m[key], key
    py_link, na_link = _without_resends(py.metrics["link"]), _without_resends(na.metrics["link"])
    waits = {key: na_link.pop(key) for key in WAIT_COUNTERS}
    assert py_link == na_link and WAIT_COUNTERS.isdisjoint(py_link)
    assert all(isinstance(v, int) and v >= 0 for v in waits.values())
    assert na.metrics["end_reason"] == "completed" and na.metrics["link"]["lost"] == 0


def test_three_phase_canfd_with_sensors_and_a_speed_step_over_udp(tmp_path: Path) -> None:
    py, na = _pair(_three(sensors=SENSORS, link="udp"), tmp_path)
    _assert_same(py, na)
    assert py.mcap_path is not None and na.mcap_path is not None
    _assert_same_frames(read_frames(py.mcap_path), read_frames(na.mcap_path))  # set-up, Setpoints, every period
    assert np.unique(na.outcome.periods.all()["speed_ref"]).size == 2


@pytest.mark.parametrize(("make", "link"), [(_three, "udp,fd=false"), (_mirrored, "udp"), (_six, "udp,fd=false")])
def test_classic_can_mirrored_and_six_phases_over_udp(make: Any, link: str) -> None:
    py, na = _pair(make(link=link))
    _assert_same(py, na)


def test_native_target_serves_udp_only_and_stops_when_idle() -> None:
    port = free_udp_ports(1)[0]
    cmd = [sys.executable, "-m", "pmsm_hil.app.cli.main", "target", "--native"]
    out = subprocess.run([*cmd, "--link", f"udp:{port}:9", "--idle-timeout", "0.3"], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 0 and "target stopped (idle 0.3 s)" in out.stdout and "(native)" in out.stdout
    assert out.stdout.startswith("ready udp:") and '"foreign_dropped": 0' in out.stdout
    out = subprocess.run([*cmd, "--link", f"udp:{port}:9", "--parent-pid", "1"], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 0 and "target stopped (parent exited)" in out.stdout
    out = subprocess.run([*cmd, "--link", "virtual"], capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and out.stderr.strip().splitlines()[-1] == \
        "hil: error: --native: serves udp, serial and socketcan links only (here: 'virtual')"
