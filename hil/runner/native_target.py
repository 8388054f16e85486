"""The native target: `hil target --native` serves the C target core and reference firmware on a UDP link from
a C loop (hil/native/target_udp.c), so a cross-process run measures the link, not a second interpreter.

Python opens the socket (the same binding and one-line errors as the Python target) and prints the ready line;
C agrees each run's session (the host's HELLO), serves frames and stops on SIGTERM/SIGINT, the idle timeout or
the death of the parent (PR_SET_PDEATHSIG, as `serve` in process.py, plus a getppid check).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.runner.native_link import native_lib
from pmsm_hil.hil.runner.native_udp import SPIN_NS, udp_bus, udp_counters, udp_handle
from pmsm_hil.protocol.links import open_link
from pmsm_hil.sim_target.process import die_with_parent

_REASONS = {1: "signal", 2: "parent exited", 3: "idle"}


@dataclass(slots=True)
class NativeServed:
    """How a native serve ended: the core's counters, the link's counters and why it stopped."""

    counters: dict[str, int]
    link_stats: dict[str, int]
    reason: str


def serve_native(link_spec: str, *, role: str = "target", max_idle_s: float | None = None,
                 parent_pid: int | None = None, on_ready: Callable[[], None] | None = None) -> NativeServed:
    """Serve the C target core on the UDP link `link_spec` until an ending (see the module docstring)."""
    ffi, lib = native_lib()
    orphaned = die_with_parent(parent_pid) if parent_pid is not None else (lambda: False)
    link = open_link(link_spec, role)  # type: ignore[arg-type]
    try:
        bus = udp_bus(link)
        if bus is None:
            raise ParameterError(f"--native: serves udp links only (here: {link_spec!r})")
        lib.hil_core_init()
        u = udp_handle(ffi, bus, target_role=True, spin_ns=SPIN_NS)
        if on_ready is not None:
            on_ready()
        if orphaned():
            end = 2
        else:
            idle_ns = 0 if max_idle_s is None else int(max_idle_s * 1e9)
            end = int(lib.nt_serve(u, idle_ns, parent_pid or 0))
        c = lib.hil_core_counters()
        counters = {name: int(getattr(c, name)) for name in ("measurements", "commands", "config_writes",
                                                              "config_rejected", "faults")}
        stats = link.stats.as_dict()
        for name, value in udp_counters(u).items():
            stats[name] += value
        reason = _REASONS.get(end, "?")
        if end == 3 and max_idle_s is not None:
            reason = f"idle {max_idle_s:g} s"
        return NativeServed(counters, stats, reason)
    finally:
        link.close()
