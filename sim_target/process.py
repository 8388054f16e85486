"""The virtual target as its own process: busy-polls its link and serves the firmware stub."""

from __future__ import annotations

import signal
from types import FrameType

from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.links import link_profile, open_link
from pmsm_hil.sim_target.firmware import controller_by_name
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
        target = SimTarget(link, FrameCodec(link_profile(link_spec)))
        if controller is not None:
            cid = controller_by_name(controller).id
            target.firmware.select_controller(cid)
            target.controller_id = cid
        target.run_forever(lambda: stop["flag"])
        return target
    finally:
        link.close()
