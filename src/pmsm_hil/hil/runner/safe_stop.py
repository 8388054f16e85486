"""The confirmed safe stop (docs/runner.md, "Safe stop on every exit path"): on every ending the host sends the
disabling Setpoint and the target must answer it with a HeartbeatTarget in state idle within
`SAFE_STOP_TIMEOUT_S` (wall time). Unconfirmed, a completed run becomes a safety stop (exit 3, "safe stop not
confirmed"; exit 130 when a Ctrl-C or SIGTERM ended the wait); any other ending keeps its code and its reason
says it too. metrics.json says what was observed (`safe_stop_confirmed`, `safe_stop_wait_ms`,
`safe_stop_observed`).
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass
from typing import Any, Final

from pmsm_hil.hil.runner.contract import EndCode
from pmsm_hil.hil.runner.target_client import TargetClient
from pmsm_hil.protocol.ids import NODE_STATE_NAMES, Mode, NodeState
from pmsm_hil.protocol.links.shared_bus import bus_starved_reason

#: how long the target may take to confirm the disabling Setpoint [s] (wall time)
SAFE_STOP_TIMEOUT_S: Final = 0.5
#: pause between two looks at the link while waiting [s]
_POLL_PAUSE_S = 0.0002


@dataclass(frozen=True, slots=True)
class SafeStop:
    """What followed the disabling Setpoint: `sent` (it left the host), `confirmed` (HeartbeatTarget idle in
    time), `wait_ms` (from sending to the confirmation, or the whole wait), `observed` (one line)."""

    sent: bool
    confirmed: bool
    wait_ms: float
    observed: str
    #: a Ctrl-C or SIGTERM ended the wait (the run still writes every output)
    interrupted: bool = False

    def metrics(self) -> dict[str, Any]:
        """The metrics.json keys (`safe_stop_confirmed` is null when the Setpoint could not be sent)."""
        return {"safe_stop_confirmed": self.confirmed if self.sent else None,
                "safe_stop_wait_ms": self.wait_ms, "safe_stop_observed": self.observed}


def _state_name(state: int) -> str:
    try:
        return f"{NODE_STATE_NAMES[NodeState(state)]} ({state})"
    except ValueError:
        return f"undefined ({state})"


def disable_and_confirm(client: TargetClient, controller_id: int, timeout_s: float = SAFE_STOP_TIMEOUT_S,
                        mode: int = Mode.SPEED) -> SafeStop:
    """Send the disabling Setpoint and wait up to `timeout_s` for a HeartbeatTarget in state idle."""
    with contextlib.suppress(Exception):  # a broken link is reported by the send below
        client.serve()  # frames already on their way are not the answer
    client.heartbeats.clear()
    shared = bool(getattr(client, "shared", False))  # a client of a shared bus (TargetClient.shared)
    frames0, bus0 = client.frames_in, client.bus.frames if shared else 0
    t0 = time.perf_counter()
    try:
        client.set_setpoint(enable=False, mode=int(mode), reference=0.0, controller_id=controller_id)
    except Exception as exc:  # the link failed: said in the metrics
        return SafeStop(False, False, 0.0, f"disabling Setpoint not sent: {type(exc).__name__}: {exc}")
    seen: list[int] = []
    try:
        while True:
            try:
                client.serve()
            except Exception as exc:
                ms = (time.perf_counter() - t0) * 1e3
                return SafeStop(True, False, ms, f"link failed while waiting for the confirmation: {exc}")
            ms = (time.perf_counter() - t0) * 1e3
            while client.heartbeats:
                hb = client.heartbeats.popleft()
                if hb.state == int(NodeState.IDLE):
                    return SafeStop(True, True, ms, "HeartbeatTarget state idle")
                seen.append(hb.state)
            if ms > timeout_s * 1e3:
                break
            time.sleep(_POLL_PAUSE_S)
    except KeyboardInterrupt:  # a second Ctrl-C / SIGTERM ends the wait, never the outputs
        ms = (time.perf_counter() - t0) * 1e3
        return SafeStop(True, False, ms, f"interrupted (Ctrl-C or SIGTERM) after {ms:.0f} ms of waiting for the "
                                         "confirmation", interrupted=True)
    other = client.frames_in - frames0 - len(seen)
    starved = _bus_starved(client, bus0, ms, timeout_s) if shared else None
    if starved is not None:  # other nodes' frames, not the target, kept the confirmation from being read
        return SafeStop(True, False, ms, starved)
    if seen or other:
        beats = f"{len(seen)} HeartbeatTarget (last state {_state_name(seen[-1])})" if seen else "no HeartbeatTarget"
        got = f"{beats} and {other} other frame(s)"
    else:
        got = "no frame at all"
    return SafeStop(True, False, ms, f"no HeartbeatTarget in state idle within {timeout_s * 1e3:g} ms of the "
                                     f"disabling Setpoint ({got})")


def _bus_starved(client: TargetClient, bus0: int, ms: float, timeout_s: float) -> str | None:
    """A shared bus: the reason naming the bus when other nodes' frames came at BUS_STARVE_FPS or more during
    the wait (the confirmation may be queued behind them), else None."""
    return bus_starved_reason(client.bus_name, client.bus.frames - bus0, ms / 1e3,
                              f"no HeartbeatTarget in state idle read within {timeout_s * 1e3:g} ms of the "
                              "disabling Setpoint", client.backlog)


def settle_ending(out: Any, stop: SafeStop) -> bool:
    """Fold the safe stop into a LoopOutcome `out` (`target_disabled`, `safe_stop`, and when unconfirmed the
    ending: exit 3 after a completed run, the reason extended otherwise). True when the plant must now be put
    in the safe state (it was not yet)."""
    out.target_disabled = stop.sent
    out.safe_stop = stop
    if stop.confirmed:
        return False
    note = f"safe stop not confirmed: {stop.observed}"
    if out.end_code == int(EndCode.COMPLETED):
        out.end_code = int(EndCode.INTERRUPTED if stop.interrupted else EndCode.SAFETY_STOP)
        bus = stop.observed.startswith("bus ")  # the bus's ending: its name first
        out.end_reason = (f"{stop.observed}; safe stop not confirmed" if bus else note) + \
            "; inverter put in the safe state (zero vector)"
    else:
        out.end_reason = f"{out.end_reason}; {note}"
    was_safe = bool(out.safe_state)
    out.safe_state = True
    return not was_safe


__all__ = ["SAFE_STOP_TIMEOUT_S", "SafeStop", "disable_and_confirm", "settle_ending"]
