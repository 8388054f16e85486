"""Wait until a target answers on its link: the host sends the disabling Setpoint and the target confirms it with
a HeartbeatTarget in state idle (the safe-stop handshake of docs/runner.md), retried until a deadline."""

from __future__ import annotations

import time

from pmsm_hil.hil.runner.safe_stop import disable_and_confirm
from pmsm_hil.hil.runner.target_client import TargetClient
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.links import open_link
from pmsm_hil.protocol.links.kinds import link_profile


def wait_heartbeat(link_spec: str, timeout_s: float, *, attempt_s: float = 0.5) -> float | None:
    """Seconds until the target on `link_spec` (the host's end) confirmed a disabling Setpoint, or None when it did
    not within `timeout_s` [s] (each attempt waits `attempt_s` [s])."""
    t0 = time.monotonic()
    link = open_link(link_spec, "host")
    try:
        client = TargetClient(link, FrameCodec(link_profile(link_spec)))
        while True:
            if disable_and_confirm(client, controller_id=0, timeout_s=attempt_s).confirmed:
                return time.monotonic() - t0
            if time.monotonic() - t0 >= timeout_s:
                return None
    finally:
        link.close()
