"""The native loop's links to a target in another process (src/pmsm_hil/hil/runner/c/links/nl_link.h): the host's open
link — a UDP socket, a serial port, a SocketCAN socket — driven by C for a run's periods.

Python opens the link, configures the target and sends the Setpoints through it; for the periods the C loop
drives the same link. The hiludp and hilserial buses are C links already (src/pmsm_hil/protocol/links/wire_bus.py):
the loop takes the bus's own C state (socket or port, link sequence numbers, UDP session, authentication, a
packet half received, counters), so nothing is handed over or back. A python-can SocketCAN bus is Python's: its
descriptor goes to a C state of its own (`fill`) and what C learnt back to the bus (`hand_back`). Each link kind
is one `Wire` (wire_udp.py, wire_serial.py, wire_socketcan.py; wire_kinds.py lists them). Waiting for a frame
busy-polls for `SPIN_NS`, then blocks.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pmsm_hil.hil.runner.core_link import NativeLoopUnavailableError
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


def _nothing(ffi: Any, state: Any, bus: Any) -> None:
    """A wire with nothing to hand back but its counters."""


@dataclass(frozen=True, slots=True)
class Wire:
    """One link kind of the native loop. `bus_of(link)`: the bus under an opened link this wire drives (None:
    another kind); `fill(ffi, state, bus, target_role)`: a C state (`struct`) of its own from the bus as it is now,
    None when the bus is a C link whose own state (`WireBus.c_state_address`) the loop drives; `hand_back(ffi,
    state, bus)`: what the bus learns from C after a run; `make_link`: the C function making the state an
    nl_link_t."""

    struct: str
    make_link: str
    bus_of: Callable[[Link], Any | None]
    fill: Callable[[Any, Any, Any, bool], None] | None = None
    hand_back: Callable[[Any, Any, Any], None] = _nothing


class WireHandle:
    """The C state a run drives on `bus` and the nl_link_t over it (kept alive together): the bus's own C state
    (a C bus), else one filled from the bus. `release` ends the run's use of it."""

    def __init__(self, wire: Wire, ffi: Any, lib: Any, bus: Any, *, target_role: bool,
                 spin_ns: int | None = None) -> None:
        self.wire, self.ffi, self.bus = wire, ffi, bus
        self.own = wire.fill is None
        if wire.fill is None:
            if ffi.sizeof(wire.struct) != bus.c_state_size:
                raise NativeLoopUnavailableError(
                    f"the {wire.struct} of the loop's extension ({ffi.sizeof(wire.struct)} bytes) is not the bus's "
                    f"({bus.c_state_size} bytes): rebuild the package (pip install -e .)")
            self.state = ffi.cast(f"{wire.struct} *", bus.c_state_address)
        else:
            self.state = ffi.new(f"{wire.struct} *")
            wire.fill(ffi, self.state, bus, target_role)
        #: the bus's receives block at once (spin_ns 0); a run's receives spin first, adapting from nothing
        self.state.spin = ffi.new("nl_spin_t *")[0]
        self.state.spin.spin_ns = default_spin_ns() if spin_ns is None else spin_ns
        self._blocked_before = int(self.state.stats.blocked)
        self._target_role_before: int | None = None
        if self.own and hasattr(self.state, "target_role"):  # a UDP bus end adopts a HELLO; a run's host does not
            self._target_role_before = int(self.state.target_role)
            self.state.target_role = 1 if target_role else 0
        self.link = ffi.new("nl_link_t *")
        getattr(lib, wire.make_link)(self.link, self.state)

    def unreported(self) -> dict[str, int]:
        """The C link's LinkStats counters the bus's own `link_stats` do not show (by name): all of a C state of
        its own, none of the bus's own C state (its `link_stats` read it)."""
        if self.own:
            return {}
        return {name: int(getattr(self.state.stats, name)) for name in COUNTERS}

    def waits(self) -> dict[str, int]:
        """How the C link's receives waited in this run: `blocked` (spins that ran out, then ppoll),
        `spin_backoffs` (times it went to blocking at once: a contended machine), `spin_early_ends` (back-offs
        ended early)."""
        st, sp = self.state.stats, self.state.spin
        return {"blocked": int(st.blocked) - self._blocked_before, "spin_backoffs": int(sp.backoffs),
                "spin_early_ends": int(sp.early_ends)}

    def release(self) -> None:
        """After the run: what the bus continues from (a C state of its own: handed back; the bus's own: its
        receives block at once again, a UDP bus end adopts its peer's HELLO again)."""
        if not self.own:
            self.wire.hand_back(self.ffi, self.state, self.bus)
            return
        self.state.spin = self.ffi.new("nl_spin_t *")[0]
        if self._target_role_before is not None:
            self.state.target_role = self._target_role_before


class NativeWireLink(LinkFacade):
    """The host's link to a target in another process, usable by `TargetClient` between runs of the C loop and
    by the C loop itself (`attach`, `detach`); `fd`: the host's frame profile is CAN FD."""

    def __init__(self, link: Link, bus: Any, wire: Wire, ffi: Any, lib: Any, fd: bool) -> None:
        #: the end this wire drives (a C wire end, or a python-can SocketCAN bus): `link_end` reads it
        self.link, self.end, self.wire = link, bus, wire
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
    def bus(self) -> Any:
        """The python-can bus under the link (a C wire end's python-can face, made on first use: `BusLink.bus`)."""
        return getattr(self.link, "bus", self.end)

    @property
    def other_process(self) -> bool:
        """The target runs in another process or on a board: replies take wall time (True)."""
        return True

    def attach(self, c: Any, lockstep_timeout_s: float) -> None:
        """Give the loop's nl_config_t `c` the link as it is now."""
        self.handle = WireHandle(self.wire, self.ffi, self.lib, self.end, target_role=False)
        c.target_link.link = self.handle.link
        c.target_link.lockstep_timeout_ns = int(lockstep_timeout_s * 1e9)
        c.target_link.sil_debug = self.sil_debug if self.sil_debug is not None else self.ffi.NULL

    def detach(self) -> None:
        """After the run: the C link's counters into `stats` (unless they are the bus's own), the link back to
        Python."""
        h = self.handle
        if h is None:
            return
        for name, value in h.unreported().items():
            setattr(self.stats, name, getattr(self.stats, name) + value)
        for name, value in h.waits().items():
            self.waits[name] = self.waits.get(name, 0) + value
        h.release()
        self.handle = None
