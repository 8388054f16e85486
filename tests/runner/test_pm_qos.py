"""The CPUs' wake-up latency held for real-time runs (the UDP pair at 50 µs): the PM QoS request
(src/pmsm_hil/hil/runner/pm_qos.py), when a run holds it, and how a spawned target waits for frames in real time."""

from __future__ import annotations

import os
import struct
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from pmsm_hil.app.cli.main import main
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner import target_setup
from pmsm_hil.hil.runner.loop_run import pm_qos_latency_us
from pmsm_hil.hil.runner.pm_qos import LEAVE, PM_QOS_FILE, cpu_latency_held
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.hil.runner.target_setup import REALTIME_SPIN_MIN_CPUS, realtime_target_spin_us
from pmsm_hil.hil.runner.wire import NativeWireLink


def test_the_request_is_the_32_bit_value_cyclictest_writes_and_ends_with_the_block(tmp_path: Path) -> None:
    qos = tmp_path / "cpu_dma_latency"
    qos.write_bytes(b"")
    with cpu_latency_held(0, str(qos)) as hold:
        assert hold.held_us == 0 and hold.refused is None and hold.warning() is None
        assert qos.read_bytes() == struct.pack("=i", 0)
    with cpu_latency_held(25, str(qos)) as hold:
        assert hold.held_us == 25 and qos.read_bytes()[:4] == struct.pack("=i", 25)


def test_a_refused_request_is_a_warning_naming_the_file_and_the_option(tmp_path: Path) -> None:
    missing = tmp_path / "no-such-device"
    with cpu_latency_held(0, str(missing)) as hold:
        assert hold.held_us is None and hold.refused is not None and str(missing) in hold.refused
        warning = hold.warning()
    assert warning is not None and warning.startswith("--cpu-dma-latency: the CPUs' wake-up latency was not held")
    with cpu_latency_held(0, str(tmp_path)) as hold:  # a directory: refused, not raised
        assert hold.held_us is None and hold.refused is not None
    with cpu_latency_held(LEAVE, str(missing)) as hold:  # -1: nothing asked, nothing refused
        assert hold.held_us is None and hold.refused is None and hold.warning() is None


class _Conn:
    def __init__(self, link: Any) -> None:
        self.host_link = link


def _cfg(**kw: Any) -> RunConfig:
    scenario = load_scenario("steady").with_overrides(settle_s=0.0, duration_s=0.01)
    return replace(RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=scenario, controller="mpcc"), **kw)


def test_a_run_holds_the_latency_in_real_time_with_its_target_in_another_process() -> None:
    wire = object.__new__(NativeWireLink)  # only its type matters here
    assert pm_qos_latency_us(_cfg(mode="realtime"), _Conn(wire)) == 0  # type: ignore[arg-type]
    assert pm_qos_latency_us(_cfg(mode="realtime"), _Conn(object())) == LEAVE  # type: ignore[arg-type]
    assert pm_qos_latency_us(_cfg(mode="lockstep", cpu_dma_latency_us=0), _Conn(wire)) == LEAVE  # type: ignore[arg-type]
    assert pm_qos_latency_us(_cfg(mode="realtime", cpu_dma_latency_us=-1), _Conn(wire)) == LEAVE  # type: ignore[arg-type]
    assert pm_qos_latency_us(_cfg(mode="realtime", cpu_dma_latency_us=10), _Conn(object())) == 10  # type: ignore[arg-type]
    with pytest.raises(ParameterError, match="--cpu-dma-latency must be -1"):
        _cfg(cpu_dma_latency_us=-2)


def test_a_spawned_target_blocks_in_real_time_when_no_cpu_is_left_for_its_spin(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(target_setup.os, "sched_getaffinity", lambda _pid: {0, 1})
    assert realtime_target_spin_us(_cfg(mode="realtime"), native=True) == 0.0
    assert realtime_target_spin_us(_cfg(mode="lockstep"), native=True) is None
    assert realtime_target_spin_us(_cfg(mode="realtime"), native=False) is None  # the Python target does not spin
    monkeypatch.setattr(target_setup.os, "sched_getaffinity", lambda _pid: set(range(REALTIME_SPIN_MIN_CPUS)))
    assert realtime_target_spin_us(_cfg(mode="realtime"), native=True) is None


def _exit_code(argv: list[str]) -> int:
    """`hil ARGV`'s exit code (argparse ends a bad value with SystemExit 2)."""
    try:
        return main(argv)
    except SystemExit as exc:
        return int(exc.code or 0)


def test_run_and_target_options_refuse_bad_values(capsys: pytest.CaptureFixture[str]) -> None:
    assert _exit_code(["run", "--mode", "realtime", "--cpu-dma-latency", "-5", "--duration", "0.01"]) == 2
    assert "--cpu-dma-latency must be -1 (leave it) or a latency of 0 µs or more" in capsys.readouterr().err
    assert _exit_code(["target", "--link", "udp", "--spin-us", "-1"]) == 2
    assert "--spin-us must be 0..1000000 µs" in capsys.readouterr().err
    assert _exit_code(["target", "--link", "udp", "--spin-us", "0"]) == 2
    assert "--spin-us: with --native only" in capsys.readouterr().err
    # the bench declares it as `hil run` does (the run-option schema): the same parse and range
    assert _exit_code(["bench", "realtime", "--cpu-dma-latency", "x"]) == 2
    assert "--cpu-dma-latency must be an integer, got 'x'" in capsys.readouterr().err
    assert _exit_code(["bench", "realtime", "--cpu-dma-latency", "-5", "--links", "inproc"]) == 2
    assert "--cpu-dma-latency must be -1 (leave it) or a latency of 0 µs or more" in capsys.readouterr().err


def test_a_real_time_run_over_udp_holds_it_and_one_in_process_does_not() -> None:
    from pmsm_hil.hil.runner.run import run_closed_loop
    from pmsm_hil.protocol.links.wire_bus import free_udp_ports

    host, target = free_udp_ports(2)
    res = run_closed_loop(_cfg(mode="realtime", link=f"udp:{host}:{target}", target="spawn", tolerate=10_000,
                               watchdog_periods=10_000))
    can_hold = os.access(PM_QOS_FILE, os.W_OK)
    assert res.metrics["cpu_dma_latency_us"] == (0 if can_hold else None)
    assert any(w.startswith("--cpu-dma-latency") for w in res.metrics["warnings"]) is (not can_hold)
    inproc = run_closed_loop(_cfg(mode="realtime")).metrics
    assert inproc["cpu_dma_latency_us"] is None and not any("--cpu-dma-latency" in w for w in inproc["warnings"])


def test_a_run_refused_the_request_says_so_and_goes_on(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Without the right to the PM QoS file (not root) a real-time run over a link still runs, and warns."""
    from pmsm_hil.hil.runner import pm_qos
    from pmsm_hil.hil.runner.run import run_closed_loop
    from pmsm_hil.protocol.links.wire_bus import free_udp_ports

    monkeypatch.setattr(pm_qos, "PM_QOS_FILE", str(tmp_path / "no-pm-qos-here"))
    host, target = free_udp_ports(2)
    res = run_closed_loop(_cfg(mode="realtime", link=f"udp:{host}:{target}", target="spawn", tolerate=10_000,
                               watchdog_periods=10_000))
    assert res.metrics["cpu_dma_latency_us"] is None and res.metrics["end_period"] >= 1
    lines = [w for w in res.metrics["warnings"] if w.startswith("--cpu-dma-latency")]
    assert len(lines) == 1 and str(tmp_path / "no-pm-qos-here") in lines[0], res.metrics["warnings"]
