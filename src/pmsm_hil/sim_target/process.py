"""The virtual target as its own process: polls its link (waits in its receive when idle) and serves the firmware
stub.

A spawned target (`hil run --target spawn`) must not outlive its host: `serve(parent_pid=...)` asks Linux for
SIGKILL when the parent dies (prctl PR_SET_PDEATHSIG) and also stops once `os.getppid()` changes (other
systems, or a parent that died before the prctl); `max_idle_s` stops it after that long without a frame.
"""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from types import FrameType

from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.links import Link, link_profile, open_link
from pmsm_hil.protocol.links.kernel_drops import link_kernel_drops
from pmsm_hil.protocol.links.wire_core import link_socket_drops
from pmsm_hil.sim_target.firmware import controller_by_name
from pmsm_hil.sim_target.target import SimTarget

#: idle timeout [s] of a target spawned by the runner (`hil target --idle-timeout`); a run sends every period
SPAWNED_IDLE_TIMEOUT_S = 30.0
#: how long an idle target waits in its link's receive between its stop checks [s] (SIGTERM, the parent's death
#: and the idle timeout are seen within it); a target that answers frames polls between them
IDLE_BLOCK_S = 0.05
#: `hil target` prints "ready SPEC" once its link is open (the runner waits for it) and, when it stops,
#: "link stats: {json}" with its link counters (the runner reads it after stopping a spawned target)
READY_LINE = "ready"
#: a SIL target process prints this line once the firmware's `hil_app_init` returned (after the ready line: the
#: host then tells a hang in hil_app_init from one in hil_app_config)
SIL_INIT_LINE = "sil initialised"
LINK_STATS_LINE = "link stats:"
_PR_SET_PDEATHSIG = 1


@dataclass(slots=True)
class Served:
    """How a serve ended: the target (its counters), the link's counters and why it stopped."""

    target: SimTarget
    link_stats: dict[str, int]
    reason: str


def die_with_parent(parent_pid: int) -> Callable[[], bool]:
    """SIGKILL this process when its parent exits (Linux prctl: nobody is left to read its report, and the
    kernel frees its port at once); returns a check that is true once `parent_pid` is no longer the parent
    (the fallback elsewhere, and for a parent that died before the prctl)."""
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0)
        except (OSError, AttributeError):
            pass
    return lambda: os.getppid() != parent_pid


def _idle_check(link: Link, max_idle_s: float) -> Callable[[], bool]:
    """True once no frame was accepted for max_idle_s (datagrams that the link drops do not count)."""
    last = [link.stats.frames_rx, time.monotonic()]

    def idle() -> bool:
        now, rx = time.monotonic(), link.stats.frames_rx
        if rx != last[0]:
            last[0], last[1] = rx, now
        return now - last[1] > max_idle_s

    return idle


def serve(link_spec: str, controller: str | None = None, *, role: str = "target",
          max_idle_s: float | None = None, parent_pid: int | None = None,
          on_ready: Callable[[], None] | None = None) -> Served:
    """Serve until SIGTERM/SIGINT, `max_idle_s` without a frame, or the death of `parent_pid`; `on_ready` runs
    once the link is open. Link errors (e.g. a port in use) raise before `on_ready`."""
    stop = {"flag": False}

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop["flag"] = True

    signal.signal(signal.SIGTERM, on_signal)
    signal.signal(signal.SIGINT, on_signal)
    orphaned = die_with_parent(parent_pid) if parent_pid is not None else (lambda: False)
    link = open_link(link_spec, role)  # type: ignore[arg-type]
    try:
        target = SimTarget(link, FrameCodec(link_profile(link_spec)))
        if controller is not None:
            cid = controller_by_name(controller).id
            target.firmware.select_controller(cid)
            target.controller_id = cid
        idle = _idle_check(link, max_idle_s) if max_idle_s is not None else (lambda: False)
        reason = ""

        def should_stop() -> bool:
            nonlocal reason
            if orphaned():
                reason = "parent exited"
            elif stop["flag"]:
                reason = "signal"
            elif idle():
                reason = f"idle {max_idle_s:g} s"
            return bool(reason)

        if on_ready is not None:
            on_ready()
        if not orphaned():
            target.run_forever(should_stop, block_s=IDLE_BLOCK_S)
        stats = {**link.stats.as_dict(), **link_socket_drops(link), **link_kernel_drops(link)}
        return Served(target, stats, reason or "parent exited")
    finally:
        link.close()
