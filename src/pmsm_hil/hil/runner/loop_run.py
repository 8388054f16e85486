"""Which loop a run uses (`--loop`), the connection to the native loop's C target core, and the native run:
the C loop where it supports the run, the Python `ClosedLoop` otherwise with the reason in the metrics."""

from __future__ import annotations

import errno
import os
from collections.abc import Callable
from typing import Any

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.load_fmu.errors import LoadFmuCrashError
from pmsm_hil.hil.runner.block_sink import RunSink
from pmsm_hil.hil.runner.callback_link import NativePyLink
from pmsm_hil.hil.runner.core_link import NativeCoreLink, NativeLoopUnavailableError, native_lib
from pmsm_hil.hil.runner.loop import NativeLoop
from pmsm_hil.hil.runner.loop_config import NativeOptions, support_problem
from pmsm_hil.hil.runner.loop_load_fmu import ended_while_initialising
from pmsm_hil.hil.runner.loop_outcome import LoopOutcome
from pmsm_hil.hil.runner.plant_setup import build_plant
from pmsm_hil.hil.runner.pm_qos import LEAVE
from pmsm_hil.hil.runner.reference_loop import require_reference_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.safe_stop import SAFE_STOP_TIMEOUT_S
from pmsm_hil.hil.runner.target_client import TargetClient
from pmsm_hil.hil.runner.target_setup import TargetConnection, connect_target
from pmsm_hil.hil.runner.wire import NativeWireLink
from pmsm_hil.hil.runner.wire_kinds import NATIVE_WIRES
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.links import link_kind


def python_loop_reason(cfg: RunConfig) -> str | None:
    """None: the run uses the C loop (every run of the product); "--loop python" when the test suite's reference
    loop was asked (ParameterError without one). A run the C loop cannot do (a machine kind without a native
    kernel, the extension not built) is a ParameterError naming the reason: there is no other loop to fall back
    to."""
    if cfg.loop == "python":
        require_reference_loop()
        return "--loop python"
    try:
        _, lib = native_lib()
        problem = support_problem(cfg, lib)
    except NativeLoopUnavailableError as exc:
        problem = str(exc)
    if problem is not None:
        raise ParameterError(f"--loop {cfg.loop}: {problem}")
    return None


def connect_native(cfg: RunConfig, silent_after: int | None = None) -> TargetConnection:
    """The host's client on the C target core (the in-process target on the virtual link); on a target in
    another process over UDP, serial or SocketCAN (spawned: the native target, `hil target --native`) through
    the descriptor the C loop takes over; on any other target and link (python-can adapters, in-process
    Python or SIL targets, QEMU, a serial socket) through the callback link (`NativePyLink`). `silent_after`: the
    in-process target ignores the Measurements after this many (a test's fault injection)."""
    spec = cfg.link_spec
    profile = link_kind(spec).profile(spec)
    ffi, lib = native_lib()
    fd = profile == "canfd"
    if in_core(cfg) and cfg.fault_spec is None:
        try:
            link = NativeCoreLink(fd=fd, silent_after=silent_after)
        except NativeLoopUnavailableError:  # the C core serves another run in this process: the Python target
            pass
        else:
            client = TargetClient(link, FrameCodec(profile))
            return TargetConnection(client, link, inproc_result=lambda: None)
    # a SIL library in its own process is served by the native target on a wire; QEMU and an in-process SIL
    # library are reached through their Python links
    native_wire = cfg.target_path is None or cfg.sil_isolated
    wire = NATIVE_WIRES.get(spec.kind.lower()) if native_wire else None
    if in_core(cfg) and cfg.fault_spec is not None:
        wire = None  # faults between the loop and the in-process Python target, as the Python loop injects them
    conn = connect_target(cfg, native_target=wire is not None and cfg.target in ("auto", "spawn"))
    bus = wire.bus_of(conn.host_link) if wire is not None else None
    native: NativeWireLink | NativePyLink
    if wire is not None and bus is not None and conn.inproc_result is None and cfg.fault_spec is None:
        native = NativeWireLink(conn.host_link, bus, wire, ffi, lib, fd=fd)
        if conn.sil_debug is not None:  # an isolated SIL target: its torque reference through shared memory
            native.sil_debug = conn.sil_debug.pointer(ffi)
    else:  # an in-process target served in Python, or no descriptor for C (serial:socket://...): through Python
        if cfg.target.startswith("stm32g4:"):  # the firmware's FDCAN1 set-up decides: classic CAN or CAN FD frames
            fd = bool(getattr(conn.host_link, "fd", fd))
        native = _board_link(cfg, conn, ffi, lib, fd) or NativePyLink(conn.host_link, ffi, lib, fd=fd,
                                                                 pump=conn.client.pump,
                                                                 inproc_result=conn.inproc_result)
    conn.host_link = conn.client.link = native
    return conn


def _board_link(cfg: RunConfig, conn: TargetConnection, ffi: Any, lib: Any, fd: bool) -> NativePyLink | None:
    """The C link to the virtual board with register-level firmware (its Measurements and Commands in C), None for
    any other target."""
    if not cfg.target.startswith("stm32g4:"):
        return None
    from pmsm_hil.hil.runner.board_native_link import NativeBoardLink
    from pmsm_hil.sim_target.stm32g4.link import BoardLink

    if not isinstance(conn.host_link, BoardLink) or conn.inproc_result is not None:
        return None

    return NativeBoardLink(conn.host_link, ffi, lib, fd=fd, pump=conn.client.pump)


def in_core(cfg: RunConfig) -> bool:
    """The run's target is the C target core of the loop itself: the in-process target on the virtual link."""
    return cfg.target in ("auto", "inproc") and cfg.link_spec.kind == "virtual"


def connect_loop_target(cfg: RunConfig, python_reason: str | None,
                        connect_python: Callable[[], TargetConnection],
                        silent_after: int | None = None) -> tuple[TargetConnection, str | None]:
    """The target of the loop `python_reason` chose: the C loop's (`connect_native`), or the reference loop's
    (`connect_python`, test suite only)."""
    if python_reason is None:
        return connect_native(cfg, silent_after), None
    return connect_python(), python_reason


def run_native(cfg: RunConfig, conn: TargetConnection, cid: int, sink: RunSink) -> LoopOutcome:
    """The run through the C loop, feeding `sink` block by block."""
    link = conn.host_link
    assert isinstance(link, NativeCoreLink | NativeWireLink | NativePyLink)
    fault = conn.client.faults[0] if conn.client.faults else None
    guest_address, ns_per_insn = conn.guest_progress()
    plant = build_plant(cfg)
    opts = NativeOptions(record_frames=sink.logger is not None,
                         fault=(fault.code, fault.detail) if fault is not None else None, target_pid=conn.target_pid(),
                         guest_insns_address=guest_address, guest_ns_per_insn=ns_per_insn,
                         first_duties=conn.duties_at_start(plant.sample()))
    try:
        loop = NativeLoop(cfg, plant, conn.client, link, cid, opts, sink=sink)
    except LoadFmuCrashError as exc:  # the load FMU's process crashed or hung in its set-up
        return ended_while_initialising(cfg, conn.client, cid, sink.logger, exc, conn.own_time(SAFE_STOP_TIMEOUT_S))
    except KeyboardInterrupt as exc:  # Ctrl-C/SIGTERM stopped the load FMU's set-up (deferred: nothing else raises)
        if cfg.load_fmu_model is None:
            raise
        return ended_while_initialising(cfg, conn.client, cid, sink.logger, exc, conn.own_time(SAFE_STOP_TIMEOUT_S))
    sink.loop_periods = loop.completed_periods
    spec = cfg.fault_spec
    faulty = link.install_faults(spec) if spec is not None and isinstance(link, NativePyLink) else None
    sink.faulty = faulty
    outcome = loop.run()
    if faulty is not None:
        outcome.link_faults = dict(faulty.counts)
    outcome.trace = sink.window.tail.array()
    return outcome


def pm_qos_latency_us(cfg: RunConfig, conn: TargetConnection) -> int:
    """The CPUs' wake-up latency a run holds [µs] (pm_qos.py; LEAVE: none): `--cpu-dma-latency`, by default 0 in
    real time with the target in another process (each period then waits for a blocked process to wake: 40–60 µs
    from a sleeping vCPU, ~5 µs from a polling one), else none (in process nothing on a period's path blocks, and
    polling idle CPUs only give a hypervisor more to take back)."""
    if cfg.mode != "realtime":
        return LEAVE
    if cfg.cpu_dma_latency_us is not None:
        return cfg.cpu_dma_latency_us
    link = conn.host_link
    other = isinstance(link, NativeCoreLink | NativeWireLink | NativePyLink) and link.other_process
    return 0 if other else LEAVE


def realtime_warnings(cfg: RunConfig, conn: TargetConnection) -> list[str]:
    """What the real-time set-up of the native loop was refused (mlockall, --rt-priority, --cpu), one line each;
    --rt-priority / --cpu given to a run of the Python loop."""
    link = conn.host_link
    if not isinstance(link, NativeCoreLink | NativeWireLink | NativePyLink):
        asked = [opt for opt, given in (("--rt-priority", cfg.rt_priority), ("--cpu", cfg.cpu is not None)) if given]
        return [f"{' and '.join(asked)}: not applied, they act on the native loop and this run used the Python "
                f"loop"] if asked else []
    mlock, sched, affinity = link.rt_errnos
    lines = []
    if mlock:
        lines.append(f"real time: mlockall refused ({os.strerror(mlock)}; raise `ulimit -l` or grant CAP_IPC_LOCK): "
                     "page faults may delay periods")
    if sched:
        why = "needs CAP_SYS_NICE or an rtprio limit (ulimit -r)" if sched == errno.EPERM else os.strerror(sched)
        lines.append(f"--rt-priority {cfg.rt_priority}: SCHED_FIFO not permitted ({why}); the loop ran at normal "
                     "priority")
    if affinity:
        lines.append(f"--cpu {cfg.cpu}: CPU affinity refused ({os.strerror(affinity)}); the loop ran on any CPU")
    return lines
