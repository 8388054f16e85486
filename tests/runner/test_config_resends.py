"""`TargetClient.configure` resends unacknowledged ConfigParams (a target still starting); the resends and the
target's repeated ConfigAcks are counted apart (`config_resent`, `config_acks_repeated` in metrics.json's `link`),
so two runs' link counters compare whatever the wall clock did at start-up (the CI VM's Python target)."""

from __future__ import annotations

import subprocess
import sys
import time
from types import SimpleNamespace
from typing import Any

import pytest

from pmsm_hil.hil.runner import run as run_module
from pmsm_hil.hil.runner.target_client import DutViolationError, TargetClient
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.errors import LinkError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.ids import ParamId, Status
from pmsm_hil.protocol.messages import ConfigAck, ConfigParam


class _SlowTarget:
    """Acknowledges every ConfigParam it is sent, but only `delay_s` after the first one reached it."""

    def __init__(self, delay_s: float) -> None:
        self.codec = FrameCodec("canfd")
        self.decoder = self.codec.decoder(ordered=False)
        self.delay_s = delay_s
        self.first: float | None = None
        self.held: list[Frame] = []
        self.received = 0

    def send(self, frames: list[Frame]) -> None:
        for frame in frames:
            msg = self.decoder.feed(frame)
            assert isinstance(msg, ConfigParam)
            self.received += 1
            self.first = time.perf_counter() if self.first is None else self.first
            self.held.extend(self.codec.encode(ConfigAck(param_id=msg.param_id, value=msg.value,
                                                         status=int(Status.OK))))

    def poll(self) -> Frame | None:
        if self.first is None or time.perf_counter() - self.first < self.delay_s or not self.held:
            return None
        return self.held.pop(0)


def test_resends_and_their_acks_are_counted_apart() -> None:
    target = _SlowTarget(delay_s=0.05)
    client = TargetClient(target, FrameCodec("canfd"))  # type: ignore[arg-type]
    client.configure({ParamId.RS: 0.5}, timeout_s=5.0, resend_s=0.01)
    assert client.config_resent >= 1  # 0.05 s without an answer: resent every 0.01 s
    assert target.received == 1 + client.config_resent
    assert client.config_acks_repeated == client.config_resent  # every copy was answered, the first one taken
    assert client.decoder.stats.messages == target.received


def test_a_prompt_target_gets_no_resend() -> None:
    target = _SlowTarget(delay_s=0.0)
    client = TargetClient(target, FrameCodec("canfd"))  # type: ignore[arg-type]
    client.configure({ParamId.RS: 0.5, ParamId.POLE_PAIRS: 3.0}, timeout_s=5.0, resend_s=10.0)
    assert (client.config_resent, client.config_acks_repeated, target.received) == (0, 0, 2)


class _BrokenClient:
    """A client whose resend meets the closed socket of a target that died."""

    def configure(self, _parameters: object) -> None:
        raise LinkError("serial:fd:29: cannot send frame 0x210: send failed: Broken pipe")


def _conn(proc: subprocess.Popen[bytes] | None) -> Any:
    return SimpleNamespace(client=_BrokenClient(), process=proc)


def test_a_link_error_while_the_target_process_has_ended_is_the_targets_end() -> None:
    """A SIL firmware that crashed while being configured, on a loaded machine: the resend's broken pipe came before
    the client's pump saw the death (the whole suite beside load 7); the run must name the crash, not fail."""
    proc = subprocess.Popen([sys.executable, "-c", "import os, signal; os.kill(os.getpid(), signal.SIGSEGV)"])
    cfg = SimpleNamespace(target_parameters=dict)
    with pytest.raises(DutViolationError, match=r"the target process ended \(SIGSEGV\): .*Broken pipe"):
        run_module._configure(_conn(proc), cfg)  # type: ignore[arg-type]


def test_a_link_error_with_the_target_alive_or_in_process_stays_the_links() -> None:
    cfg = SimpleNamespace(target_parameters=dict)
    with pytest.raises(LinkError):
        run_module._configure(_conn(None), cfg)  # type: ignore[arg-type]
    proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        with pytest.raises(LinkError):
            run_module._configure(_conn(proc), cfg)  # type: ignore[arg-type]
    finally:
        proc.kill()
        proc.wait()
