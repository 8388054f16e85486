"""Frame links: python-can buses (virtual, SocketCAN, PCAN, ...) and the hiludp / hilserial plugins."""

from pmsm_hil.protocol.links.faults import DirectionFaults, FaultEvent, FaultSpec, FaultyLink, parse_fault_spec
from pmsm_hil.protocol.links.kinds import LINK_KINDS, LinkKind, SpawnSpecs, link_kind, link_profile, register_link_kind
from pmsm_hil.protocol.links.link import BusLink, Link, open_link
from pmsm_hil.protocol.links.spec import LinkSpec, parse_spec
from pmsm_hil.protocol.links.stats import LinkStats

__all__ = ["LINK_KINDS", "BusLink", "DirectionFaults", "FaultEvent", "FaultSpec", "FaultyLink", "Link", "LinkKind",
           "LinkSpec", "LinkStats", "SpawnSpecs", "link_kind", "link_profile", "open_link", "parse_fault_spec",
           "parse_spec", "register_link_kind"]
