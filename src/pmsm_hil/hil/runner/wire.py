"""The native loop's links to a target in another process (src/pmsm_hil/hil/runner/c/links/nl_link.h): the host's open
link — a UDP socket, a serial port, a SocketCAN socket — handed to C for a run's periods and back afterwards.

Python opens the link, configures the target and sends the Setpoints through it; for the periods the C loop
takes the same descriptor and what the link continues from (link sequence numbers, a UDP session, a serial
packet half received) and hands them back with its LinkStats counters afterwards. Each link kind is one `Wire`
(wire_udp.py, wire_serial.py, wire_socketcan.py; wire_kinds.py lists them): its C state, the C
function making that state an nl_link_t, and how its state goes to C and back. Waiting for a frame busy-polls
for `SPIN_NS`, then blocks.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pmsm_hil.hil.runner.link_facade import LinkFacade
from pmsm_hil.protocol.links import Link
from pmsm_hil.protocol.links.stats import LinkStats

#: busy-poll this long for a frame before blocking in ppoll [ns]: a lockstep round trip on an idle machine
#: is well inside it, and a loaded machine gets the core back instead of two spinning processes
SPIN_NS = 50_000


def default_spin_ns() -> int:
    """`SPIN_NS`, or 0 (always block) when this process may run on one CPU only: there a spin just delays the
    peer it waits for."""
    return SPIN_NS if len(os.sched_getaffinity(0)) > 1 else 0


#: LinkStats counters the C links keep (nl_link_stats_t fields of the same names)
COUNTERS = tuple(LinkStats.__slots__)


def _fill_auth(ffi: Any, lib: Any, state: Any, bus: Any, target_role: bool) -> None:
    """A wire with authenticated frames (its C state has an `auth` field, its bus a FrameAuth): the key, the MAC
    context and both freshness counters to C."""
    auth = getattr(bus, "auth", None)
    if auth is None or not hasattr(state, "auth"):
        return
    a = ffi.addressof(state, "auth")
    lib.hil_auth_init(a, auth.key, len(auth.key), 1 if target_role else 0)
    lib.hil_auth_set_context(a, auth.context, len(auth.context))
    a.tx_fresh, a.rx_fresh = auth.tx_fresh, auth.rx_fresh


def _hand_back_auth(state: Any, bus: Any) -> None:
    """The freshness counters the C link reached, back to the bus's FrameAuth."""
    auth = getattr(bus, "auth", None)
    if auth is not None and hasattr(state, "auth") and state.auth.on:
        auth.tx_fresh, auth.rx_fresh = int(state.auth.tx_fresh), int(state.auth.rx_fresh)


def _nothing(ffi: Any, state: Any, bus: Any) -> None:
    """A wire with nothing to hand back but its counters."""


@dataclass(frozen=True, slots=True)
class Wire:
    """One link kind of the native loop. `bus_of(link)`: the bus under an opened link this wire drives (None:
    another kind); `fill(ffi, state, bus, target_role)`: the C state (`struct`) from the bus as it is now;
    `hand_back(ffi, state, bus)`: what the bus continues from after C used it; `make_link`: the C function
    making the state an nl_link_t."""

    struct: str
    make_link: str
    bus_of: Callable[[Link], Any | None]
    fill: Callable[[Any, Any, Any, bool], None]
    hand_back: Callable[[Any, Any, Any], None] = _nothing


class WireHandle:
    """A wire's C state on `bus` and the nl_link_t over it (kept alive together)."""

    def __init__(self, wire: Wire, ffi: Any, lib: Any, bus: Any, *, target_role: bool,
                 spin_ns: int | None = None) -> None:
        self.wire, self.ffi, self.bus = wire, ffi, bus
        self.state = ffi.new(f"{wire.struct} *")
        self.state.spin.spin_ns = default_spin_ns() if spin_ns is None else spin_ns
        wire.fill(ffi, self.state, bus, target_role)
        _fill_auth(ffi, lib, self.state, bus, target_role)
        self.link = ffi.new("nl_link_t *")
        getattr(lib, wire.make_link)(self.link, self.state)

    def counters(self) -> dict[str, int]:
        """The C link's LinkStats counters by name."""
        return {name: int(getattr(self.state.stats, name)) for name in COUNTERS}

    def waits(self) -> dict[str, int]:
        """How the C link's receives waited: `blocked` (spins that ran out, then ppoll), `spin_backoffs` (times
        it went to blocking at once: a contended machine), `spin_early_ends` (back-offs ended early)."""
        st, sp = self.state.stats, self.state.spin
        return {"blocked": int(st.blocked), "spin_backoffs": int(sp.backoffs), "spin_early_ends": int(sp.early_ends)}

    def hand_back(self) -> None:
        """Give the bus what it continues from (link sequence numbers, bytes of a packet half received)."""
        self.wire.hand_back(self.ffi, self.state, self.bus)
        _hand_back_auth(self.state, self.bus)


class NativeWireLink(LinkFacade):
    """The host's link to a target in another process, usable by `TargetClient` between runs of the C loop and
    by the C loop itself (`attach`, `detach`); `fd`: the host's frame profile is CAN FD."""

    def __init__(self, link: Link, bus: Any, wire: Wire, ffi: Any, lib: Any, fd: bool) -> None:
        self.link, self.bus, self.wire = link, bus, wire
        self.ffi, self.lib = ffi, lib
        self.fd = fd
        self.stats: LinkStats = link.stats
        #: errno of what the last run's real-time set-up was refused: mlockall, SCHED_FIFO, CPU affinity (0: ok)
        self.rt_errnos: tuple[int, int, int] = (0, 0, 0)
        self.handle: WireHandle | None = None
        #: how the C loop's receives waited over its runs (`WireHandle.waits`)
        self.waits: dict[str, int] = {}
        #: an `nl_sil_debug_t *` a SIL target process writes its torque references to (None: none)
        self.sil_debug: Any = None

    @property
    def other_process(self) -> bool:
        """The target runs in another process or on a board: replies take wall time (True)."""
        return True

    def attach(self, c: Any, lockstep_timeout_s: float) -> None:
        """Give the loop's nl_config_t `c` the link as it is now."""
        self.handle = WireHandle(self.wire, self.ffi, self.lib, self.bus, target_role=False)
        c.link = self.handle.link
        c.lockstep_timeout_ns = int(lockstep_timeout_s * 1e9)
        c.sil_debug = self.sil_debug if self.sil_debug is not None else self.ffi.NULL

    def detach(self) -> None:
        """After the run: the C link's counters into `stats`, its state back to the bus."""
        h = self.handle
        if h is None:
            return
        for name, value in h.counters().items():
            setattr(self.stats, name, getattr(self.stats, name) + value)
        for name, value in h.waits().items():
            self.waits[name] = self.waits.get(name, 0) + value
        h.hand_back()
        self.handle = None
