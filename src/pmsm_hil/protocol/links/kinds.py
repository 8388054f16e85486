"""The registry of link kinds: every fact about a SPEC kind (`virtual`, `udp`, `serial`, `can`, python-can
adapters) kept once — how its bus opens, its default frame profile, what bounds its wire time, how a spawned
target mirrors it, and which target `--target auto` picks for it.

A new link kind is one `register_link_kind(LinkKind(...))` call (docs/recipes.md, "A new link kind"); kinds
not registered are python-can interfaces by name (`socketcan`, `pcan`, `kvaser`, ...: `PYTHON_CAN_ADAPTER`).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Literal

from pmsm_hil.protocol.errors import LinkSpecError
from pmsm_hil.protocol.links.auth import key_of_options
from pmsm_hil.protocol.links.budget import LinkBudget, link_budget
from pmsm_hil.protocol.links.spec import LinkSpec, Role, parse_spec

if TYPE_CHECKING:  # python-can and the wire buses are imported where a bus is opened (a `--help` needs neither)
    import can

    from pmsm_hil.protocol.links.wire_core import WireEnd

Profile = Literal["can", "canfd"]
#: What limits one period's wire time: nothing (in-process, loopback), a serial line or a CAN bus.
Wire = Literal["none", "serial", "can"]
#: Target kind `--target auto` picks: the in-process sim target, a spawned `hil target`, or a board.
AutoTarget = Literal["inproc", "spawn", "external"]
#: (bus, description) of an opened link end: a python-can bus, or a C wire end (wire_core.py: no python-can)
BusFactory = Callable[[LinkSpec, Role], "tuple[can.BusABC | WireEnd, str]"]

DEFAULT_VIRTUAL_CHANNEL = "pmsm_hil"
DEFAULT_UDP_PORTS: dict[str, tuple[int, int]] = {"host": (47310, 47311), "target": (47311, 47310)}
_TRUE = ("true", "1", "yes", "on")
_FALSE = ("false", "0", "no", "off")


@dataclass(frozen=True, slots=True)
class SpawnSpecs:
    """Link specs of a spawned target: the host's end, the target process's end, and descriptors the host
    keeps open until the run ends (the pty slave)."""

    host: str
    target: str
    keep_open: list[int] = field(default_factory=list)


def _same_spec(spec: str, ls: LinkSpec) -> SpawnSpecs:
    return SpawnSpecs(spec, spec)


def _python_can_bus(ls: LinkSpec, role: Role) -> tuple[can.BusABC, str]:
    import can

    opts = dict(ls.options)
    if ls.channel is not None:
        opts["channel"] = ls.channel
    return can.Bus(interface=ls.kind, **opts), f"{ls.kind}:{ls.channel or ''}"


@dataclass(frozen=True, slots=True)
class LinkKind:
    """Facts of one link kind. `fd_default`: frame profile when the SPEC has no `fd=` option (CAN FD sized
    frames unless a real classic-CAN bus); `wire`: what bounds the real-time rate (`budget`);
    `mirror(spec, parsed)`: the specs of a spawned target; `auto_target(parsed)`: `--target auto`."""

    name: str
    summary: str
    open_bus: BusFactory = _python_can_bus
    fd_default: bool = False
    wire: Wire = "can"
    mirror: Callable[[str, LinkSpec], SpawnSpecs] = _same_spec
    auto_target: Callable[[LinkSpec], AutoTarget] = lambda ls: "external"

    def profile(self, ls: LinkSpec) -> Profile:
        """'canfd' or 'can': the SPEC's `fd=` option, else the kind's default."""
        fd = ls.options.get("fd")
        if fd is None:
            return "canfd" if self.fd_default else "can"
        text = str(fd).strip().lower()
        if text not in _TRUE + _FALSE:
            raise LinkSpecError(f"link option fd must be true or false, got {fd!r}")
        return "canfd" if text in _TRUE else "can"

    def budget(self, ls: LinkSpec, rate_hz: float, phases: int) -> LinkBudget | None:
        """Worst-case wire budget at `rate_hz` [Hz] for `phases`-phase frames, None without a wire limit.
        Serial: `baudrate` option (default 3 Mbaud); CAN: `bitrate` (1 Mbit/s), `data_bitrate` (5 Mbit/s)."""
        opts = ls.options
        if self.wire == "none":
            return None
        if self.wire == "serial":
            return link_budget("serial", phases, baud=int(opts.get("baudrate", 3_000_000)), rate_hz=rate_hz,
                               auth=authenticated(ls))
        return link_budget(self.profile(ls), phases, bitrate=int(opts.get("bitrate", 1_000_000)),
                           data_bitrate=int(opts.get("data_bitrate", 5_000_000)), rate_hz=rate_hz)


def authenticated(ls: LinkSpec) -> bool:
    """True when frames on this link will carry the authentication trailer: a key is given, or the link is a
    spawned target's pty (authenticated unless `auth=off`)."""
    opts = ls.options
    if "key" in opts or "keyfile" in opts:
        return True
    return ls.channel == "pty" and str(opts.get("auth", "on")).lower() not in ("off", "false")


LINK_KINDS: dict[str, LinkKind] = {}


def register_link_kind(kind: LinkKind) -> LinkKind:
    """Add (or replace) a link kind by its name (lower case)."""
    LINK_KINDS[kind.name.lower()] = kind
    return kind


#: Any python-can interface not registered here (socketcan, pcan, kvaser, slcan, gs_usb, ...).
PYTHON_CAN_ADAPTER = LinkKind("python-can adapter", "NAME:CHANNEL[,opt=val...] any python-can interface "
                              "(socketcan:can0, pcan:PCAN_USBBUS1, kvaser:0, slcan:/dev/ttyACM0)")


def link_kind(spec: str | LinkSpec) -> LinkKind:
    """The registered kind of a SPEC (or parsed spec); python-can adapters for any other interface name."""
    ls = parse_spec(spec) if isinstance(spec, str) else spec
    return LINK_KINDS.get(ls.kind.lower(), PYTHON_CAN_ADAPTER)


def link_profile(spec: str) -> Profile:
    """Frame profile of a link SPEC ('canfd' or 'can')."""
    ls = parse_spec(spec)
    return link_kind(ls).profile(ls)


# --- the built-in kinds -------------------------------------------------------------------------------
def _open_virtual(ls: LinkSpec, role: Role) -> tuple[can.BusABC, str]:
    import can
    from can import CanProtocol

    opts = dict(ls.options)
    fd = bool(opts.pop("fd", True))
    opts.setdefault("receive_own_messages", False)
    channel = ls.channel or DEFAULT_VIRTUAL_CHANNEL
    proto = CanProtocol.CAN_FD if fd else CanProtocol.CAN_20
    return can.Bus(interface="virtual", channel=channel, protocol=proto, **opts), f"virtual:{channel}"


def _open_udp(ls: LinkSpec, role: Role) -> tuple[WireEnd, str]:
    from pmsm_hil.protocol.links.wire_core import UdpEnd, parse_udp_channel

    if ls.channel is None:
        local, remote = DEFAULT_UDP_PORTS[role]
        channel = f"{local}:{remote}"
    else:
        channel = ls.channel
        try:
            parse_udp_channel(channel)
        except ValueError as exc:
            raise LinkSpecError(str(exc)) from exc
    opts = dict(ls.options)
    key = key_of_options(opts)
    return UdpEnd(channel=channel, auth_key=key, auth_role=role, **opts), f"udp:{channel}"


def _mirror_udp(spec: str, ls: LinkSpec) -> SpawnSpecs:
    """``udp:L:R[@HOST]`` gives the target ``udp:R:L[@HOST]`` (same options); ``udp`` without ports takes two
    ports free now on 127.0.0.1 (not the fixed defaults, which another target may hold)."""
    head, sep, opts = spec.partition(",")
    _, _, channel = head.strip().partition(":")
    if not channel:
        from pmsm_hil.protocol.links.wire_core import free_udp_ports

        a, b = free_udp_ports(2)
        return SpawnSpecs(f"udp:{a}:{b}{sep}{opts}", f"udp:{b}:{a}{sep}{opts}")
    ports, at, host = channel.partition("@")
    local, _, remote = ports.partition(":")
    return SpawnSpecs(spec, f"udp:{remote}:{local}{at}{host}{sep}{opts}")


def _open_serial(ls: LinkSpec, role: Role) -> tuple[WireEnd, str]:
    from pmsm_hil.protocol.links.wire_core import SerialEnd

    if ls.channel is None:
        raise LinkSpecError("link spec serial: needs a port, e.g. serial:/dev/ttyACM0,baudrate=3000000")
    opts = dict(ls.options)
    key = key_of_options(opts)
    return SerialEnd(channel=ls.channel, auth_key=key, auth_role=role, **opts), f"serial:{ls.channel}"


def _mirror_serial(spec: str, ls: LinkSpec) -> SpawnSpecs:
    """``serial:pty`` makes a pseudo-terminal pair: the host takes the master descriptor, the target process
    opens the slave by its path (kept open by the host until the run ends)."""
    if ls.channel != "pty":
        return SpawnSpecs(spec, spec)
    _, sep, opts = spec.partition(",")
    master, slave = os.openpty()
    tail = sep + opts
    return SpawnSpecs(f"serial:fd:{master}{tail}", f"serial:{os.ttyname(slave)}{tail}", [slave])


def _open_can_config(ls: LinkSpec, role: Role) -> tuple[can.BusABC, str]:
    import can

    opts: dict[str, Any] = dict(ls.options)
    if ls.channel is not None:
        opts["channel"] = ls.channel
    return can.Bus(**opts), "can (python-can configuration)"


register_link_kind(LinkKind("virtual", "virtual[:CHANNEL] python-can virtual bus, in-process", _open_virtual,
                            fd_default=True, wire="none", auto_target=lambda ls: "inproc"))
register_link_kind(LinkKind("udp", "udp[:LOCALPORT:REMOTEPORT[@HOST]] UDP unicast (hiludp), another process",
                            _open_udp, fd_default=True, wire="none", mirror=_mirror_udp))
register_link_kind(LinkKind("hiludp", "hiludp:... the UDP plugin through python-can", fd_default=True,
                            wire="none"))
register_link_kind(LinkKind("serial", "serial:PORT|pty[,baudrate=N] COBS + CRC-16 serial (hilserial)",
                            _open_serial, fd_default=True, wire="serial", mirror=_mirror_serial,
                            auto_target=lambda ls: "spawn" if ls.channel == "pty" else "external"))
register_link_kind(LinkKind("hilserial", "hilserial:... the serial plugin through python-can", fd_default=True,
                            wire="serial"))
register_link_kind(LinkKind("can", "can[,opt=val...] python-can configuration file and environment",
                            _open_can_config))


def _open_socketcan(ls: LinkSpec, role: Role) -> tuple[can.BusABC, str]:
    """python-can's socketcan bus with its kernel receive drops counted (socketcan_bus.py)."""
    try:
        from pmsm_hil.protocol.links.socketcan_bus import SocketcanLinkBus
    except ImportError:  # python-can's socketcan interface is Linux only
        return _python_can_bus(ls, role)
    opts = dict(ls.options)
    return SocketcanLinkBus(channel=ls.channel or "", **opts), f"socketcan:{ls.channel or ''}"


register_link_kind(LinkKind("socketcan", "socketcan:IF[,fd=true][,rx_frames=N] Linux SocketCAN (can0, vcan0); "
                            "the receive buffer holds N frames (4096), kernel drops counted", _open_socketcan))

__all__ = ["LINK_KINDS", "PYTHON_CAN_ADAPTER", "LinkKind", "SpawnSpecs", "link_kind", "link_profile",
           "register_link_kind"]
