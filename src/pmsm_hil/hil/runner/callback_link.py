"""The native loop over any Python link: the callback link of the C loop (`nl_py_link`, c/loop_py.h), whose send and
receive are the two Python functions below.

Links the C loop cannot take over as a descriptor — python-can adapters (PCAN, Kvaser, Vector, python-can's own
socketcan, ...), the link to an in-process Python or SIL target (served by its `pump` inside the receive), QEMU's
UART and mailbox links — carry the C loop's frames through Python: per period, one `send` per frame and the
receives of the reply. The plant, codec, contract and record stay in C.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

from pmsm_hil.hil.runner.fault_setup import pump_after_faults
from pmsm_hil.hil.runner.link_facade import LinkFacade
from pmsm_hil.hil.runner.target_client import DRAIN_MAX
from pmsm_hil.hil.runner.wire import default_spin_ns
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links import Link
from pmsm_hil.protocol.links.faults import FaultSpec, FaultyLink
from pmsm_hil.protocol.links.stats import LinkStats

_CALLBACKS_DEFINED: set[int] = set()


def _define_callbacks(ffi: Any) -> None:
    """Define `nl_py_send` / `nl_py_recv` of the loop extension once (cffi `extern "Python"`)."""
    if id(ffi) in _CALLBACKS_DEFINED:
        return

    @ffi.def_extern()  # type: ignore[untyped-decorator]
    def nl_py_send(ctx: Any, f: Any) -> int:
        bridge: NativePyLink = ffi.from_handle(ctx)
        try:
            return bridge.on_send(f)
        except BaseException as exc:  # the loop thread must not unwind through C
            bridge.fail(exc)
            return -1

    @ffi.def_extern()  # type: ignore[untyped-decorator]
    def nl_py_recv(ctx: Any, f: Any, deadline_ns: int) -> int:
        bridge: NativePyLink = ffi.from_handle(ctx)
        try:
            return bridge.on_recv(f, deadline_ns)
        except BaseException as exc:
            bridge.fail(exc)
            return 0

    @ffi.def_extern()  # type: ignore[untyped-decorator]
    def nl_py_diag(ctx: Any, split_ns: Any, torque_ref: Any, full_miss: Any) -> int:
        bridge: NativePyLink = ffi.from_handle(ctx)
        try:
            return bridge.on_diag(split_ns, torque_ref, full_miss)
        except BaseException as exc:  # the loop thread must not unwind through C
            bridge.fail(exc)
            return 0

    @ffi.def_extern()  # type: ignore[untyped-decorator]
    def nl_py_period(ctx: Any, t_s: float) -> None:
        bridge: NativePyLink = ffi.from_handle(ctx)
        bridge.on_period(t_s)

    _CALLBACKS_DEFINED.add(id(ffi))


class NativePyLink(LinkFacade):
    """A Python `link` the C loop drives through callbacks, usable by `TargetClient` between runs as the link
    itself. `pump`: called before each receive (an in-process target's service, or a liveness check of a
    target's process); `inproc_result`: given for an in-process target (which answers inside its pump, so a
    receive never waits): what it says of its last step (stage split [ns], torque reference [N·m], candidate
    miss), recorded with each reply as the Python loop does; `fd`: the host's
    frame profile is CAN FD. An exception in a callback (a bus error) stops the loop and is raised after it
    (`error`)."""

    def __init__(self, link: Link, ffi: Any, lib: Any, fd: bool, pump: Callable[[], object] | None = None,
                 inproc_result: Callable[[], object] | None = None) -> None:
        _define_callbacks(ffi)
        self.link, self.ffi, self.lib, self.fd, self.pump = link, ffi, lib, fd, pump
        self.inproc_result = inproc_result
        self._burst = 0  # frames returned in a row at or past a receive's deadline (on_recv)
        self.stats: LinkStats = link.stats
        #: errno of what the last run's real-time set-up was refused: mlockall, SCHED_FIFO, CPU affinity (0: ok)
        self.rt_errnos: tuple[int, int, int] = (0, 0, 0)
        #: the first exception a callback raised in the last run (None: none)
        self.error: BaseException | None = None
        #: called once when a callback fails (the loop sets it to stop the run)
        self.on_error: Callable[[], None] = lambda: None
        self.waits: dict[str, int] = {}
        #: a receive polls this long before it blocks [ns] (the native wires' rule: 0 on a single CPU)
        self.spin_ns = default_spin_ns()
        self._handle: Any = None
        self._c_link: Any = None
        #: link fault injection (`install_faults`): the wrapper, its run clock [s] and the period's virtual deadline
        self.faulty: FaultyLink | None = None
        self.clock_s = 0.0
        self._ts_s = 0.0
        self._realtime = False
        self._delayed = False
        self._period_deadline_s = 0.0
        self._t0_ns = 0
        self._pump_unfaulted = pump

    @property
    def bus(self) -> Any:
        """The python-can bus under the link (through a fault wrapper), None if it has none."""
        link: Any = self.link
        while link is not None and not hasattr(link, "bus"):
            link = getattr(link, "link", None)
        return getattr(link, "bus", None)

    @property
    def other_process(self) -> bool:
        """The target runs in another process or on a board (no `inproc_result`): replies take wall time."""
        return self.inproc_result is None

    def attach(self, c: Any, lockstep_timeout_s: float) -> None:
        """Give the loop's nl_config_t `c` this link."""
        self.error = None
        self._handle = self.ffi.new_handle(self)
        self._c_link = self.ffi.new("nl_link_t *")
        self.lib.nl_py_link(self._c_link, self._handle, 1 if self.inproc_result is not None else 0,
                            1 if self.faulty is not None else 0)
        c.target_link.link = self._c_link
        c.target_link.lockstep_timeout_ns = int(lockstep_timeout_s * 1e9)
        self._ts_s, self._realtime = float(c.timing.ts_s), bool(c.timing.realtime)
        self._delayed = self.faulty is not None and not self._realtime and self.faulty.spec.delays
        self._t0_ns = time.perf_counter_ns()

    # --- link fault injection (`--fault`) ----------------------------------------------------------------------
    def install_faults(self, spec: FaultSpec) -> FaultyLink:
        """Inject `spec` between the C loop and the link (as `fault_setup.install_faults` does for the Python
        loop, with the same clock: the period start in lockstep, wall time since the start in real time); an
        in-process target is served after the delayed frames due are released."""
        faulty = FaultyLink(self.link, spec, self.run_time_s, crc_checked=True)
        self.faulty, self.link = faulty, faulty
        self.pump = pump_after_faults(faulty, self._pump_unfaulted)
        return faulty

    def remove_faults(self) -> None:
        """The safe stop is not subject to the injected faults: the link and pump without them."""
        if self.faulty is not None:
            self.link, self.pump = self.faulty.link, self._pump_unfaulted

    def run_time_s(self) -> float:
        """Run time [s] the fault injection sees: the period start in lockstep, the wall time in real time."""
        if self._realtime:
            return (time.perf_counter_ns() - self._t0_ns) / 1e9
        return self.clock_s

    def on_period(self, t_s: float) -> None:
        """A period starts at `t_s` [s] (its Measurement is sent next)."""
        self.clock_s = t_s
        self._period_deadline_s = t_s + self._ts_s + 1e-12  # release times are sums of floats: 1 ps slack

    def _await_delayed(self, deadline_ns: int) -> Frame | None:
        """Lockstep with delayed frames (ClosedLoop._await_delayed): virtual time runs from the period start to
        its end through the release times of the delayed frames; a target in another process gets the wall-time
        deadline for its reply."""
        faulty = self.faulty
        assert faulty is not None
        while True:
            if self.pump is not None:
                self.pump()
            frame = self.link.poll()
            if frame is not None:
                return frame
            nxt = faulty.next_release_s()
            if nxt is not None and nxt <= self._period_deadline_s:
                self.clock_s = max(self.clock_s, nxt)  # the next delayed frame arrives
                continue
            if self.inproc_result is not None or time.monotonic_ns() >= deadline_ns:
                return None

    def detach(self) -> None:
        """After the run (the Python link counted its own frames)."""
        self._handle = None

    def fail(self, exc: BaseException) -> None:
        """A callback raised: keep the first exception, stop the loop."""
        if self.error is None:
            self.error = exc
            self.on_error()

    # --- the callbacks (the loop's thread) ---------------------------------------------------------------------
    def on_send(self, f: Any) -> int:
        """One frame C → link: 0."""
        self.link.send((Frame(int(f.id), bytes(self.ffi.buffer(f.data, f.len)), bool(f.fd)),))
        return 0

    def on_recv(self, f: Any, deadline_ns: int) -> int:
        """The next frame into `f` (1), or 0 when none came before `deadline_ns` (CLOCK_MONOTONIC; 0: poll). At or
        past the deadline at most DRAIN_MAX frames in a row (then 0 once): a flooded bus never empties."""
        late = deadline_ns <= 0 or time.monotonic_ns() >= deadline_ns
        if not late:
            self._burst = 0
        elif self._burst >= DRAIN_MAX:
            self._burst = 0
            return 0
        if deadline_ns > 0 and self._delayed:
            frame = self._await_delayed(deadline_ns)
        elif self.inproc_result is not None:  # an in-process target answers inside its pump: no wait
            if self.pump is not None:
                self.pump()
            frame = self.link.poll()
        elif deadline_ns <= 0:
            if self.pump is not None:  # e.g. a liveness check of the target's process
                self.pump()
            frame = self.link.poll()
        else:  # spin on poll for up to spin_ns (a blocked thread on this kind of VM wakes tens of µs late), then block
            poll, now = self.link.poll, time.monotonic_ns
            frame = poll()
            spin_end = min(deadline_ns, now() + self.spin_ns)
            while frame is None and now() < spin_end:
                frame = poll()
            if frame is None:
                timeout_s = (deadline_ns - now()) / 1e9
                frame = self.link.recv(timeout_s) if timeout_s > 0 else None
        if frame is None:
            self._burst = 0
            return 0
        self._burst += late
        data = bytes(frame.data)[:64]
        f.id, f.len, f.fd = frame.arbitration_id, len(data), 1 if frame.is_fd else 0
        self.ffi.memmove(f.data, data.ljust(64, b"\0"), 64)
        return 1

    def on_diag(self, split_ns: Any, torque_ref: Any, full_miss: Any) -> int:
        """The in-process target's last step (`inproc_result`): 1 filled, 0 nothing to say."""
        res = self.inproc_result() if self.inproc_result is not None else None
        if res is None:
            return 0
        split = res.split_ns  # type: ignore[attr-defined]
        for j in range(3):
            split_ns[j] = int(split[j])
        torque_ref[0] = float(res.torque_ref)  # type: ignore[attr-defined]
        full_miss[0] = int(getattr(res, "full_miss", 255))
        return 1

