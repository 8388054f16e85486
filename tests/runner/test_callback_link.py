"""The C period loop over any Python link (the callback link, src/pmsm_hil/hil/runner/callback_link.py): python-can
adapters, in-process Python targets on a real link, and a bus error inside a callback. Records and metrics equal the
Python loop's, bit for bit."""

from __future__ import annotations

import contextlib
import socket
import subprocess
import sys
from collections.abc import Iterator
from dataclasses import replace
from typing import Any

import pytest

from pmsm_hil.hil.runner.callback_link import NativePyLink
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.protocol.links.kinds import DEFAULT_UDP_PORTS
from pmsm_hil.protocol.links.wire_bus import free_udp_ports
from tests.runner.test_loop import SENSORS, _assert_same_metrics, _assert_same_records, _three
from tests.runner.test_wire_udp import WALL_FIELDS, WALL_METRICS, _without_resends


def _both(cfg: RunConfig) -> tuple[Any, Any]:
    runs = [run_closed_loop(replace(cfg, loop=loop)) for loop in ("python", "native")]
    assert [r.metrics["loop"] for r in runs] == ["python", "native"]
    return runs[0], runs[1]


def test_an_in_process_target_on_udp_takes_free_ports_not_the_fixed_defaults() -> None:
    """`--link udp` without ports and an in-process target: both ends are this process's, so the run takes two ports
    free now (as a spawned target's does); the fixed defaults may be held by another run on the machine (two suites
    at once failed here with "cannot bind UDP port 47311")."""
    held = []
    for port in DEFAULT_UDP_PORTS["host"]:
        sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        with contextlib.suppress(OSError):  # already held by someone else: held all the same
            sock.bind(("127.0.0.1", port))
        held.append(sock)
    try:
        res = run_closed_loop(replace(_three(link="udp", target="inproc"), loop="native"))
    finally:
        for sock in held:
            sock.close()
    assert res.metrics["end_code"] == 0, res.metrics["end_reason"]


def test_an_in_process_python_target_on_a_udp_link() -> None:
    """`--target inproc --link udp`: the Python target served by its pump inside the C loop's receives."""
    py, na = _both(_three(link="udp", target="inproc", sensors=SENSORS))
    _assert_same_records(py.outcome.periods.all(), na.outcome.periods.all())
    _assert_same_metrics(py.metrics, na.metrics)


@pytest.fixture
def native_target_ports() -> Iterator[tuple[int, int]]:
    """A native target (`hil target --native`) on UDP; yields (host port, target port)."""
    host, target = free_udp_ports(2)
    proc = subprocess.Popen([sys.executable, "-m", "pmsm_hil.app.cli.main", "target", "--native", "--link",
                             f"udp:{target}:{host}"], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        assert proc.stdout is not None and proc.stdout.readline().startswith(b"ready")
        yield host, target
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_a_python_can_adapter_to_an_external_target(native_target_ports: tuple[int, int]) -> None:
    """`hiludp` opened as python-can opens any adapter (the interface name is not a registered link kind): the
    C loop carries its frames through Python, and gives the Python loop's records."""
    host, target = native_target_ports
    cfg = _three(link=f"hiludp:{host}:{target}", target="external")
    py, na = _both(cfg)
    a, b = py.outcome.periods.all(), na.outcome.periods.all()
    assert a.shape == b.shape and a.shape[0] > 0
    for name in set(a.dtype.names or ()) - WALL_FIELDS:  # a target in another process: no stage split
        assert a[name].tobytes() == b[name].tobytes(), name
    assert py.metrics.keys() == na.metrics.keys()
    for key in py.metrics.keys() - WALL_METRICS:
        assert py.metrics[key] == na.metrics[key], key
    py_link, na_link = _wire_counters(py.metrics["link"]), _wire_counters(na.metrics["link"])
    assert py_link == na_link and na.metrics["link"]["frames_tx"] > 0


def _wire_counters(link: dict[str, Any]) -> dict[str, Any]:
    """The link counters less what the host's scheduling decides when two runs share one target: the
    configuration's resends, and `session_dropped` (datagrams of the target's other session that reach the host's
    port late: 3 in one run at load 18)."""
    out = _without_resends(link)
    dropped = out.pop("session_dropped")
    assert isinstance(dropped, int) and dropped >= 0
    return out


def test_a_bus_error_in_a_callback_ends_the_run_safely(monkeypatch: pytest.MonkeyPatch) -> None:
    """The adapter raises on its 100th frame: the C loop stops, the run ends as an internal error naming the
    exception, and the target is still disabled."""
    sent = [0]
    original = NativePyLink.on_send

    def failing(self: NativePyLink, f: Any) -> int:
        sent[0] += 1
        if sent[0] == 100:
            raise OSError("adapter unplugged")
        return original(self, f)

    monkeypatch.setattr(NativePyLink, "on_send", failing)
    res = run_closed_loop(_three(link="udp", target="inproc", loop="native"))
    assert res.metrics["end_code"] == 1 and "adapter unplugged" in res.metrics["end_reason"]
    assert res.outcome.completed_periods < 110 and res.outcome.target_disabled


FAULTS = ["drop=0.02,seed=1", "dup=0.02,seed=2", "corrupt=0.02,seed=3", "delay=30us", "jitter=80us,seed=4",
          "reorder=0.02,seed=5", "silence=0.004:0.005", "drop=0.01,dup=0.01,delay=30us,reorder.down=0.02,seed=6"]


@pytest.mark.parametrize("fault", FAULTS)
def test_link_faults_in_the_c_loop_as_in_the_python_loop(fault: str) -> None:
    """`--fault` in the C loop (the fault-injecting wrapper under its callback link, the same clock): the same
    faults, records, metrics and /link_faults counts as the Python loop, for every fault class; lockstep delays
    run on virtual time in both."""
    cfg = _three(faults=fault, tolerate=10_000)
    py, na = _both(cfg)
    _assert_same_records(py.outcome.periods.all(), na.outcome.periods.all())
    assert py.metrics.keys() == na.metrics.keys()
    for key in py.metrics.keys() - WALL_METRICS:  # the time spent in a lost reply's receive is wall time
        assert py.metrics[key] == na.metrics[key], key
    assert na.outcome.link_faults == py.outcome.link_faults and sum(na.outcome.link_faults.values()) > 0
