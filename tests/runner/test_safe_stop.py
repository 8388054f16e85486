"""The confirmed safe stop (src/pmsm_hil/hil/runner/safe_stop.py) with every reference target kind and both loops; a
target that disables without confirming ends a completed run with exit 3. The foreign target process that ignores the
disabling Setpoint: tests/runner/test_dut_contract.py."""

from __future__ import annotations

from collections import deque
from dataclasses import replace
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runlog.reader import read_frames
from pmsm_hil.hil.runner.contract import EndCode
from pmsm_hil.hil.runner.loop_outcome import LoopOutcome
from pmsm_hil.hil.runner.recorder import frame_records, period_records
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.safe_stop import disable_and_confirm, settle_ending
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.protocol.links.wire_bus import free_udp_ports
from pmsm_hil.sim_target import target as sim_target


def _cfg(**kw: Any) -> RunConfig:
    sc = load_scenario("steady").with_overrides(settle_s=0.0, duration_s=0.01)
    return RunConfig(motor=load_motor("niu2020-ipmsm"), scenario=sc, **kw)


@pytest.mark.parametrize("loop", ["native", "python"])
def test_the_in_process_target_confirms_and_the_confirmation_is_logged(loop: str, tmp_path: Any) -> None:
    res = run_closed_loop(_cfg(loop=loop, out_dir=tmp_path / "run"))
    m = res.metrics
    assert m["loop"] == loop and m["end_code"] == 0 and m["end_reason"] == "completed"
    assert m["safe_stop_confirmed"] is True and m["safe_stop_observed"] == "HeartbeatTarget state idle"
    assert 0 < m["safe_stop_wait_ms"] < 500
    frames = read_frames(tmp_path / "run" / "run.mcap")
    last_two = [(int(f["direction"]), int(f["arbitration_id"]), bytes(f["data"])[:int(f["length"])])
                for f in frames[-2:]]
    assert last_two[0][:2] == (0, 0x200) and last_two[0][2][0] == 0  # the disabling Setpoint, sent
    assert last_two[1] == (1, 0x701, bytes([1, 1, 0]))  # HeartbeatTarget node 1, idle, counter 0, received


@pytest.mark.parametrize("loop", ["native", "python"])
def test_a_spawned_target_over_udp_confirms(loop: str) -> None:
    a, b = free_udp_ports()
    m = run_closed_loop(_cfg(link=f"udp:{a}:{b}", target="spawn", loop=loop)).metrics
    assert m["loop"] == loop and m["end_code"] == 0
    assert m["safe_stop_confirmed"] is True and m["safe_stop_wait_ms"] < 500


@pytest.mark.usefixtures("target_without_heartbeats")
def test_an_in_process_target_that_does_not_confirm_ends_with_exit_3() -> None:
    res = run_closed_loop(_cfg(loop="python"))
    m = res.metrics
    assert m["end_code"] == int(EndCode.SAFETY_STOP) and res.outcome.safe_state and m["safe_state"] is True
    assert m["end_reason"] == ("safe stop not confirmed: no HeartbeatTarget in state idle within 500 ms of the "
                               "disabling Setpoint (no frame at all); inverter put in the safe state (zero vector)")
    assert m["safe_stop_confirmed"] is False and m["safe_stop_wait_ms"] >= 500 and m["target_disabled"] is True
    assert m["end_period"] == m["total_periods"] - 1 == 99


def test_a_heartbeat_in_another_state_is_no_confirmation(monkeypatch: pytest.MonkeyPatch) -> None:
    real = sim_target.SimTarget._send

    def running_heartbeats(self: sim_target.SimTarget, msg: Any) -> None:
        real(self, replace(msg, state=2) if type(msg).__name__ == "Heartbeat" else msg)

    monkeypatch.setattr(sim_target.SimTarget, "_send", running_heartbeats)
    m = run_closed_loop(_cfg(loop="python")).metrics
    assert m["end_code"] == 3 and m["safe_stop_confirmed"] is False
    assert m["safe_stop_observed"] == ("no HeartbeatTarget in state idle within 500 ms of the disabling Setpoint (1 "
                                       "HeartbeatTarget (last state running (2)) and 0 other frame(s))")


class _InterruptedClient:
    """A TargetClient stand-in whose link is served until a Ctrl-C arrives in the wait."""

    def __init__(self) -> None:
        self.heartbeats: deque[Any] = deque()
        self.frames_in = 0
        self.serves = 0

    def serve(self) -> None:
        self.serves += 1
        if self.serves == 3:
            raise KeyboardInterrupt

    def set_setpoint(self, **kw: Any) -> None:
        assert kw["enable"] is False


def test_a_second_interrupt_ends_the_wait_never_the_outputs() -> None:
    stop = disable_and_confirm(_InterruptedClient(), 1)  # type: ignore[arg-type]
    assert stop.sent and not stop.confirmed and stop.interrupted and stop.wait_ms < 100
    assert stop.observed.startswith("interrupted (Ctrl-C or SIGTERM) after ")
    out = LoopOutcome(period_records(), frame_records(), np.zeros(0), 0)
    assert settle_ending(out, stop) is True  # the plant goes to the safe state now
    assert out.end_code == int(EndCode.INTERRUPTED) and out.safe_state and out.target_disabled
    assert out.end_reason.startswith("safe stop not confirmed: interrupted")
