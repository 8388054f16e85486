"""The native loop's SocketCAN link (src/pmsm_hil/hil/runner/c/links/loop_socketcan.c): the CAN_RAW socket python-can
opened for the host's `socketcan:IF[,fd=true]` link handed to C (`SOCKETCAN_WIRE`, see wire.py); frames as python-can
writes and reads them (`struct can_frame` / `struct canfd_frame`). SocketCAN has no link state to hand back but
the kernel's drop count C read on the socket (SO_RXQ_OVFL, src/pmsm_hil/protocol/links/socketcan_bus.py)."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, Any

from pmsm_hil.hil.runner.wire import Wire
from pmsm_hil.protocol.links import Link
from pmsm_hil.protocol.links.wire_core import link_end

if TYPE_CHECKING:
    import can


def socketcan_bus(link: Link) -> can.BusABC | None:
    """The python-can SocketCAN bus under `link`, or None (a link opened without python-can has none)."""
    socketcan = sys.modules.get("can.interfaces.socketcan.socketcan")  # a SocketcanBus was opened: imported
    bus = link_end(link)
    return bus if socketcan is not None and isinstance(bus, socketcan.SocketcanBus) else None


def fill_socketcan(ffi: Any, s: Any, bus: can.BusABC, target_role: bool) -> None:
    """nl_socketcan_t `s` on `bus`'s socket (any python-can bus whose descriptor carries SocketCAN frames)."""
    from can import CanProtocol

    s.fd = bus.fileno()
    s.fd_frames = 1 if bus.protocol in (CanProtocol.CAN_FD, CanProtocol.CAN_FD_NON_ISO) else 0


def hand_back_socketcan(ffi: Any, s: Any, bus: can.BusABC) -> None:
    """The kernel drop count the C link read goes to the bus (`link.kernel_dropped`)."""
    note = getattr(bus, "note_kernel_dropped", None)
    if note is not None:
        note(int(s.kernel_dropped))


SOCKETCAN_WIRE = Wire("nl_socketcan_t", "nl_socketcan_link", socketcan_bus, fill_socketcan, hand_back_socketcan)
