"""Frame links: python-can buses (virtual, SocketCAN, PCAN, ...) and the hiludp / hilserial plugins.

The names below load on first use: importing one module of this package (the link kinds' summaries for a
`--help`, the link budget) imports neither python-can nor pyserial."""

from __future__ import annotations

from typing import TYPE_CHECKING

from pmsm_hil.lazy_names import lazy_getattr

if TYPE_CHECKING:
    from pmsm_hil.protocol.links.faults import DirectionFaults, FaultEvent, FaultSpec, FaultyLink, parse_fault_spec
    from pmsm_hil.protocol.links.kinds import (
        LINK_KINDS,
        LinkKind,
        SpawnSpecs,
        link_kind,
        link_profile,
        register_link_kind,
    )
    from pmsm_hil.protocol.links.link import BusLink, Link, open_link
    from pmsm_hil.protocol.links.spec import LinkSpec, parse_spec
    from pmsm_hil.protocol.links.stats import LinkStats

_LAZY = {
    **dict.fromkeys(("DirectionFaults", "FaultEvent", "FaultSpec", "FaultyLink", "parse_fault_spec"),
                    "pmsm_hil.protocol.links.faults"),
    **dict.fromkeys(("LINK_KINDS", "LinkKind", "SpawnSpecs", "link_kind", "link_profile", "register_link_kind"),
                    "pmsm_hil.protocol.links.kinds"),
    **dict.fromkeys(("BusLink", "Link", "open_link"), "pmsm_hil.protocol.links.link"),
    **dict.fromkeys(("LinkSpec", "parse_spec"), "pmsm_hil.protocol.links.spec"),
    "LinkStats": "pmsm_hil.protocol.links.stats",
}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())


__all__ = ["LINK_KINDS", "BusLink", "DirectionFaults", "FaultEvent", "FaultSpec", "FaultyLink", "Link", "LinkKind",
           "LinkSpec", "LinkStats", "SpawnSpecs", "link_kind", "link_profile", "open_link", "parse_fault_spec",
           "parse_spec", "register_link_kind"]
