"""`link.kernel_dropped`: frames the host kernel dropped for a link's socket, its receive buffer full (SocketCAN
links: socketcan_bus.py counts them from `SO_RXQ_OVFL`)."""

from __future__ import annotations

from typing import Any

from pmsm_hil.protocol.links.wire_core import link_end


def link_kernel_drops(link: Any) -> dict[str, int]:
    """{"kernel_dropped": N} for a link whose bus counts its kernel's receive drops (a SocketCAN link), else {}
    (LinkStats extras, metrics.json `link.kernel_dropped`)."""
    counter = getattr(link_end(link), "kernel_dropped", None)
    return {"kernel_dropped": int(counter())} if callable(counter) else {}


__all__ = ["link_kernel_drops"]
