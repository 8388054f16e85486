"""The virtual target as its own process: busy-polls its link and serves the firmware stub."""

from __future__ import annotations

import signal
from types import FrameType

from pmsm_hil.hil.runner.run_config import controller_id
from pmsm_hil.hil.runner.target_setup import link_profile
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.links import open_link
from pmsm_hil.sim_target.target import SimTarget


def serve(link_spec: str, controller: str | None = None, *, role: str = "target",
          max_idle_s: float | None = None) -> SimTarget:
    """Serve until SIGTERM/SIGINT (or max_idle_s without frames); returns the target for its counters."""
    stop = {"flag": False}

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop["flag"] = True

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    link = open_link(link_spec, role)  # type: ignore[arg-type]
    try:
        target = SimTarget(link, FrameCodec(link_profile(link_spec)))  # type: ignore[arg-type]
        if controller is not None:
            target.firmware.select_controller(controller_id(controller))
            target.controller_id = controller_id(controller)
        target.run_forever(lambda: stop["flag"])
        return target
    finally:
        link.close()
