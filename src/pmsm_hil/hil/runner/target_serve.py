"""The native target: `hil target --native` serves the C target core and reference firmware on a UDP, serial or
SocketCAN link from a C loop (src/pmsm_hil/hil/runner/c/target_serve.c), so a cross-process run measures the link, not a
second interpreter.

Python opens the link (the same binding, port set-up and one-line errors as the Python target) and prints the
ready line; C serves frames (over UDP it agrees each run's session from the host's HELLO) and stops on
SIGTERM/SIGINT, the idle timeout, the death of the parent (PR_SET_PDEATHSIG, as `serve` in process.py, plus a
getppid check) or the host closing the link (a pty's other end).

With a SIL library (`hil target --native --sil PATH`) the same C loop serves that library's copy of the core
through its function pointers: the SIL target in its own process, so a crash or an endless loop in the user's
code cannot take the runner down (src/pmsm_hil/hil/runner/sil_watch.py tells the runner's ending).
"""

from __future__ import annotations

import mmap
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.runner.core_link import native_lib
from pmsm_hil.hil.runner.sil_debug import SIL_DEBUG_BYTES
from pmsm_hil.hil.runner.wire import WireHandle
from pmsm_hil.hil.runner.wire_kinds import NATIVE_WIRES
from pmsm_hil.protocol.links import open_link, parse_spec
from pmsm_hil.protocol.links.kernel_drops import link_kernel_drops
from pmsm_hil.protocol.links.wire_core import link_socket_drops
from pmsm_hil.sim_target.process import SIL_INIT_LINE, die_with_parent
from pmsm_hil.sim_target.sil import SilFirmware


def _reasons(lib: Any) -> dict[int, str]:
    """How nt_serve ended (its NT_END_* codes, read from C through cffi) -> the reason printed."""
    return {int(lib.NT_END_SIGNAL): "signal", int(lib.NT_END_PARENT): "parent exited", int(lib.NT_END_IDLE): "idle",
            int(lib.NT_END_CLOSED): "link closed"}


def _serve_sil(ffi: Any, lib: Any, h: WireHandle, idle_ns: int, parent_pid: int, firmware: SilFirmware,
               debug_fd: int | None) -> int:
    """nt_serve_core over the SIL library's core, copying each step's torque reference to the memory of
    `debug_fd` (shared with the host) when given."""
    rx, tx = (ffi.cast(t, p) for t, p in zip(("nt_core_rx_fn", "nt_core_tx_fn"), firmware.entry_points(), strict=True))
    if debug_fd is None:
        return int(lib.nt_serve_core(h.link, idle_ns, parent_pid, rx, tx))
    steps, torque_ref = firmware.debug_sources()
    with mmap.mmap(debug_fd, SIL_DEBUG_BYTES) as shared:
        slot = ffi.from_buffer("nl_sil_debug_t *", shared)
        try:
            return int(lib.nt_serve_core_debug(h.link, idle_ns, parent_pid, rx, tx, ffi.cast("uint32_t *", steps),
                                               ffi.cast("float *", torque_ref), slot))
        finally:
            ffi.release(slot)


@dataclass(slots=True)
class NativeServed:
    """How a native serve ended: the core's counters, the link's counters and why it stopped."""

    counters: dict[str, int]
    link_stats: dict[str, int]
    reason: str


def serve_native(link_spec: str, *, role: str = "target", max_idle_s: float | None = None,
                 parent_pid: int | None = None, on_ready: Callable[[], None] | None = None,
                 sil: str | None = None, sil_debug_fd: int | None = None,
                 spin_ns: int | None = None) -> NativeServed:
    """Serve the C target core on the link `link_spec` until an ending (see the module docstring); `sil`: the
    core of this SIL library instead of the reference firmware linked in (the SIL target's own process);
    `sil_debug_fd`: memory shared with the host (loop.h nl_sil_debug_t) where each step's torque reference goes;
    `spin_ns`: how long a receive busy-polls before it blocks [ns] (None: the native wires' default, 0: block)."""
    ffi, lib = native_lib()
    # a bad library fails before the ready line; its hil_app_init runs after it, under the host's watch
    firmware = SilFirmware(sil, init=False) if sil is not None else None
    wire = NATIVE_WIRES.get(parse_spec(link_spec).kind.lower())
    if wire is None:
        *kinds, last = NATIVE_WIRES
        raise ParameterError(f"--native: serves {', '.join(kinds)} and {last} links only (here: {link_spec!r})")
    orphaned = die_with_parent(parent_pid) if parent_pid is not None else (lambda: False)
    link = open_link(link_spec, role)  # type: ignore[arg-type]
    try:
        bus = wire.bus_of(link)
        if bus is None:
            raise ParameterError(f"--native: {link_spec!r} opened no port the C loop can serve")
        if firmware is None:
            lib.hil_core_init()
        h = WireHandle(wire, ffi, lib, bus, target_role=True, spin_ns=spin_ns)
        if on_ready is not None:
            on_ready()
        if firmware is not None:
            firmware.init()
            print(SIL_INIT_LINE, flush=True)
        if orphaned():
            end = int(lib.NT_END_PARENT)
        else:
            idle_ns = 0 if max_idle_s is None else int(max_idle_s * 1e9)
            if firmware is None:
                end = int(lib.nt_serve(h.link, idle_ns, parent_pid or 0))
            else:
                end = _serve_sil(ffi, lib, h, idle_ns, parent_pid or 0, firmware, sil_debug_fd)
        names = ("measurements", "commands", "config_writes", "config_rejected", "faults")
        if firmware is None:
            c = lib.hil_core_counters()
            counters = {name: int(getattr(c, name)) for name in names}
        else:
            counters = {name: value for name, value in firmware.counters().items() if name in names}
        stats = link.stats.as_dict()
        for name, value in h.unreported().items():
            stats[name] += value
        stats.update(h.waits())
        stats.update(link_socket_drops(link))
        h.release()
        stats.update(link_kernel_drops(link))
        reason = _reasons(lib).get(end, f"end code {end}")
        if end == lib.NT_END_IDLE and max_idle_s is not None:
            reason = f"idle {max_idle_s:g} s"
        return NativeServed(counters, stats, reason)
    finally:
        link.close()
