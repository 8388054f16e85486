"""Frame links: python-can buses (virtual, SocketCAN, PCAN, ...) and the hiludp / hilserial plugins."""

from pmsm_hil.protocol.links.link import BusLink, Link, LinkSpec, open_link, parse_spec
from pmsm_hil.protocol.links.stats import LinkStats

__all__ = ["BusLink", "Link", "LinkSpec", "LinkStats", "open_link", "parse_spec"]
