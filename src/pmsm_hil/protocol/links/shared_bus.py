"""Which node sent a frame on a shared CAN bus. A real CAN bus carries other nodes' traffic; the host must not take
another node's frame for the target's. What hil.dbc says tells them apart: the target sends only its own ids
(sender Target: the Command frames, FaultTarget, ConfigAck, HeartbeatTarget); a Command answers the seq of the
Measurement the host sent; a FaultTarget names node 1 (target) and a Status code 1..6; a ConfigAck answers a
parameter the host wrote, echoing its float32 value. On a shared bus a frame of another id is **foreign**
(`bus_foreign_frames`), a frame of the target's ids whose content the target cannot have sent is **suspect**
(`bus_suspect_frames`): both are counted as bus traffic, never findings against the target. The native loop
applies the same rules in C (src/pmsm_hil/hil/runner/c/loop.c `from_target_node`).

A link is a shared bus when its kind's wire is a CAN bus (`socketcan`, python-can adapters: `LinkKind.wire`
"can"), or its SPEC says `shared=true` (e.g. `virtual:x,shared=true`, a python-can virtual bus other nodes join);
`shared=false` turns it off (a point-to-point CAN cable whose target sends malformed frames the contract should
see). An ending caused by the bus starving the run names the link: `bus_starved_reason`."""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.ids import Mode, Node, Status
from pmsm_hil.protocol.layout import load_layouts
from pmsm_hil.protocol.links.kinds import link_kind
from pmsm_hil.protocol.links.spec import parse_spec

#: the SPEC option that marks (true) or unmarks (false) a link as a shared bus (popped before python-can opens it)
SHARED_OPTION = "shared"
#: Status codes a FaultTarget may carry (VAL_TABLE_ Status without 0 ok)
FAULT_CODES = frozenset(int(s) for s in Status if s != Status.OK)
TARGET_NODE_ID = int(Node.TARGET)
#: Status not_implemented: its detail is the controller id of the Setpoint it answers
NOT_IMPLEMENTED = int(Status.NOT_IMPLEMENTED)
#: Status invalid_config: its detail is the mode of the Setpoint it answers, one of the Mode values
INVALID_CONFIG = int(Status.INVALID_CONFIG)
MODES = frozenset(int(m) for m in Mode)
#: bus frames per second, in the stretch without a Command that ended a run, from which the ending is the bus's:
#: a CAN bus at 1 Mbit/s carries at most ~8 k classic frames/s, so 500/s of other nodes' frames is a bus at
#: a sixteenth of its capacity or more, taken up by what the run did not send
BUS_STARVE_FPS = 500.0


@lru_cache(maxsize=1)
def target_ids() -> frozenset[int]:
    """Ids whose sender in hil.dbc is the Target node."""
    return frozenset(m.frame_id for m in load_layouts().values() if "Target" in m.senders)


@lru_cache(maxsize=1)
def command_ids() -> frozenset[int]:
    """The Command frame ids (every part carries `seq` in bytes 0-1, little endian)."""
    return frozenset(m.frame_id for m in load_layouts().values() if m.name.startswith("Cmd"))


@lru_cache(maxsize=1)
def target_lengths() -> dict[int, int]:
    """The payload length of each id the target sends (hil.dbc): a frame of another length is not its."""
    return {m.frame_id: m.length for m in load_layouts().values() if "Target" in m.senders}


def fault_target_id() -> int:
    return load_layouts()["FaultTarget"].frame_id


def is_shared_bus(spec: str) -> bool:
    """True when the link of `spec` is a CAN bus other nodes may share (module docstring)."""
    ls = parse_spec(spec)
    flag = ls.options.get(SHARED_OPTION)
    if flag is not None:
        return flag is True or str(flag).lower() in ("true", "1", "yes", "on")
    return link_kind(ls).wire == "can"


def command_seq(frame: Frame) -> int | None:
    """The seq a Command frame carries (None: too short)."""
    data = bytes(frame.data)
    return data[0] | data[1] << 8 if len(data) >= 2 else None


@dataclass(slots=True)
class BusTraffic:
    """Other nodes' frames seen on a shared bus: foreign ids and suspect frames of the target's ids."""

    foreign: int = 0
    suspect: int = 0

    @property
    def frames(self) -> int:
        return self.foreign + self.suspect

    @staticmethod
    def fault_plausible(frame: Frame, controller_id: int | None, mode: int | None = None) -> bool:
        """A FaultTarget the target can have sent: its length, node 1, a Status code 1..6; not_implemented names
        the controller id of the host's last Setpoint (`controller_id`; None: none sent yet), invalid_config a Mode
        value or the mode of the host's last Setpoint (`mode`: the conformance probe sends an undefined one on
        purpose) (another node's Setpoint answered, else)."""
        data = bytes(frame.data)
        if len(data) != 6 or data[0] != TARGET_NODE_ID or data[1] not in FAULT_CODES:
            return False
        detail = int.from_bytes(data[2:6], "little")
        if data[1] == INVALID_CONFIG:  # its detail is the Setpoint's mode: the host sends Mode values only
            return detail in MODES or detail == mode
        return data[1] != NOT_IMPLEMENTED or detail == controller_id


def rate_text(frames_per_s: float) -> str:
    """`1.2 k frames/s` / `340 frames/s`."""
    return f"{frames_per_s / 1e3:.1f} k frames/s" if frames_per_s >= 1e3 else f"{frames_per_s:.0f} frames/s"


def bus_starved_reason(link: str, frames: int, seconds: float, waiting_for: str, backlog: bool = False) -> str | None:
    """The ending's reason when the bus starved the run: `frames` of other nodes' traffic over `seconds` of wall
    time without what the run waited for (`waiting_for`), at BUS_STARVE_FPS or more, or any while the receive
    queue never emptied (`backlog`: the last drain was cut at its bound, what was awaited may be queued behind
    them); else None (the target's)."""
    if seconds <= 0.0 or frames <= 0 or (frames / seconds < BUS_STARVE_FPS and not backlog):
        return None
    queue = "; the receive queue never emptied" if backlog else ""
    return (f"bus {link}: {rate_text(frames / seconds)} of other nodes' frames ({frames} in {seconds:.1f} s"
            f"{queue}) starved the run ({waiting_for})")


__all__ = [
    "BUS_STARVE_FPS",
    "SHARED_OPTION",
    "BusTraffic",
    "bus_starved_reason",
    "command_ids",
    "command_seq",
    "fault_target_id",
    "is_shared_bus",
    "rate_text",
    "target_ids",
    "target_lengths",
]
