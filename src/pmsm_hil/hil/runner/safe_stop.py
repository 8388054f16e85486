"""The confirmed safe stop (docs/runner.md, "Safe stop on every exit path"): on every ending the host sends the
disabling Setpoint and the target must answer it with a HeartbeatTarget in state idle within
`SAFE_STOP_TIMEOUT_S` -- of the target's own time when the host observes its process (a SIL target process, QEMU,
a spawned target: `TargetTime`, the lockstep wait's rule), wall time for a board or an external target.
Unconfirmed, a completed run becomes a safety stop (exit 3, "safe stop not confirmed"; exit 130 when a Ctrl-C or
SIGTERM ended the wait); any other ending keeps its code and its reason says it too. A target the host kept
stopped or off the CPUs is waited for (a host stall, counted in `host_stalls`), up to the host-stall limit of wall
time, then the run ends as the host's error (exit 1), never as "safe stop not confirmed". metrics.json says what
was observed (`safe_stop_confirmed`, `safe_stop_wait_ms`, `safe_stop_observed`).
"""

from __future__ import annotations

import contextlib
import time
from dataclasses import dataclass
from typing import Any, Final

from pmsm_hil.hil.runner.contract import EndCode
from pmsm_hil.hil.runner.target_client import HostStallError, TargetClient
from pmsm_hil.hil.runner.target_time import TargetTime
from pmsm_hil.protocol.ids import NODE_STATE_NAMES, Mode, NodeState
from pmsm_hil.protocol.links.shared_bus import bus_starved_reason

#: how long the target may take to confirm the disabling Setpoint [s] (its own time when its process is observed,
#: else wall time)
SAFE_STOP_TIMEOUT_S: Final = 0.5
#: the longest wall time [s] the wait goes on while the host stalls the target's process (--host-stall-limit's
#: default; a run passes its own)
SAFE_STOP_STALL_LIMIT_S: Final = 60.0
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
    #: the time [s] the host kept the target's process stopped or off the CPUs during a wait that went past
    #: the timeout because of it (0: none)
    host_stall_s: float = 0.0
    #: the host-stall limit ended the wait: the target never had its time to confirm (the host's fault)
    host_stalled: bool = False

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
                        mode: int = Mode.SPEED, clock: TargetTime | None = None,
                        stall_limit_s: float = SAFE_STOP_STALL_LIMIT_S) -> SafeStop:
    """Send the disabling Setpoint and wait up to `timeout_s` for a HeartbeatTarget in state idle: of the target's
    own time when `clock` observes its process (a host stall goes on up to `stall_limit_s` of wall time), else
    wall time."""
    with contextlib.suppress(Exception):  # a broken link is reported by the send below
        client.serve()  # frames already on their way are not the answer
    client.heartbeats.clear()
    shared = bool(getattr(client, "shared", False))  # a client of a shared bus (TargetClient.shared)
    frames0, bus0 = client.frames_in, client.bus.frames if shared else 0
    t0 = time.perf_counter()
    if clock is not None:
        clock.start()
    try:
        client.set_setpoint(enable=False, mode=int(mode), reference=0.0, controller_id=controller_id)
    except Exception as exc:  # the link failed: said in the metrics
        return SafeStop(False, False, 0.0, f"disabling Setpoint not sent: {type(exc).__name__}: {exc}")
    seen: list[int] = []
    stalled = False
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
                    return SafeStop(True, True, ms, "HeartbeatTarget state idle", host_stall_s=_lost_s(clock, ms,
                                                                                                     timeout_s))
                seen.append(hb.state)
            if _had_its_time(clock, ms, timeout_s):
                break
            if ms > max(stall_limit_s, timeout_s) * 1e3:
                stalled = True
                break
            time.sleep(_POLL_PAUSE_S)
    except KeyboardInterrupt:  # a second Ctrl-C / SIGTERM ends the wait, never the outputs
        ms = (time.perf_counter() - t0) * 1e3
        return SafeStop(True, False, ms, f"interrupted (Ctrl-C or SIGTERM) after {ms:.0f} ms of waiting for the "
                                         "confirmation", interrupted=True, host_stall_s=_lost_s(clock, ms, timeout_s))
    lost_s = _lost_s(clock, ms, timeout_s)
    if stalled and clock is not None:
        return SafeStop(True, False, ms, f"host stall: the target's process (pid {clock.pid}) was kept stopped or "
                                         f"off the CPUs while the safe stop waited {ms / 1e3:.1f} s for its "
                                         f"confirmation (--host-stall-limit {stall_limit_s:g} s); the host's fault, "
                                         "not the firmware's", host_stall_s=lost_s, host_stalled=True)
    other = client.frames_in - frames0 - len(seen)
    starved = _bus_starved(client, bus0, ms, timeout_s) if shared else None
    if starved is not None:  # other nodes' frames, not the target, kept the confirmation from being read
        return SafeStop(True, False, ms, starved)
    if seen or other:
        beats = f"{len(seen)} HeartbeatTarget (last state {_state_name(seen[-1])})" if seen else "no HeartbeatTarget"
        got = f"{beats} and {other} other frame(s)"
    else:
        got = "no frame at all"
    return SafeStop(True, False, ms, f"no HeartbeatTarget in state idle within {timeout_s * 1e3:g} ms "
                                     f"{_clock_words(clock)}of the disabling Setpoint ({got})", host_stall_s=lost_s)


def _had_its_time(clock: TargetTime | None, ms: float, timeout_s: float) -> bool:
    """The target had `timeout_s` to confirm: of its own time while its process is observed (`clock`, read once a
    slice), else of the `ms` of wall time waited so far."""
    if clock is not None and clock.observable:
        clock.step()
        if clock.observable:
            return clock.had_s >= timeout_s
    return ms > timeout_s * 1e3


def _lost_s(clock: TargetTime | None, ms: float, timeout_s: float) -> float:
    """The host's part [s] of a wait of `ms` that went past `timeout_s` because the target could not run (0 when
    it did not, or when the target is not observed)."""
    if clock is None or not clock.watching or ms <= timeout_s * 1e3:
        return 0.0
    lost = ms / 1e3 - min(clock.had_s, ms / 1e3)
    return lost if lost >= clock.slice_s else 0.0


def _clock_words(clock: TargetTime | None) -> str:
    if clock is None or not clock.watching:
        return ""
    return "(of the emulated MCU's own time) " if clock.guest else "(of the target process's own time) "


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
    if stop.host_stall_s > 0:
        out.host_stalls += 1
        out.host_stall_s += stop.host_stall_s
    if stop.confirmed:
        return False
    note = f"safe stop not confirmed: {stop.observed}"
    if stop.host_stalled and out.end_code == int(EndCode.COMPLETED):  # the host's fault, not the firmware's
        out.end_code = int(EndCode.INTERNAL_ERROR)
        out.error = HostStallError(stop.observed)
        out.end_reason = f"{stop.observed}; inverter put in the safe state (zero vector)"
    elif out.end_code == int(EndCode.COMPLETED):
        out.end_code = int(EndCode.INTERRUPTED if stop.interrupted else EndCode.SAFETY_STOP)
        bus = stop.observed.startswith("bus ")  # the bus's ending: its name first
        out.end_reason = (f"{stop.observed}; safe stop not confirmed" if bus else note) + \
            "; inverter put in the safe state (zero vector)"
    else:
        out.end_reason = f"{out.end_reason}; {note}"
    was_safe = bool(out.safe_state)
    out.safe_state = True
    return not was_safe


__all__ = ["SAFE_STOP_STALL_LIMIT_S", "SAFE_STOP_TIMEOUT_S", "SafeStop", "disable_and_confirm", "settle_ending"]
