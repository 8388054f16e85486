"""Connects the runner to a target: in-process sim target, a spawned `hil target` process, external, a SIL
firmware library (`sil:PATH`: in a spawned `hil target --native --sil` process, or in-process with
`--sil-in-process`), a firmware ELF in QEMU (`qemu:PATH`) or on the virtual STM32G4 board (`stm32g4:PATH`).

A spawned target gets `--parent-pid` (it exits with the host) and an idle timeout; the host waits for its
"ready" line and ends the run with the target's own error if it cannot open its link (e.g. a UDP port in
use), so it never talks to whatever else holds the port. UDP links agree a session before the run.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pmsm_hil.hil.runner.loop_outcome import LoopOutcome
from pmsm_hil.hil.runner.run_config import QEMU_MAILBOX_LINK, RunConfig
from pmsm_hil.hil.runner.sil_debug import SilDebugSlot
from pmsm_hil.hil.runner.sil_watch import (
    SIL_STOP_WAIT_S,
    SOCKETPAIR_LINK,
    BusyWatch,
    InterruptGuard,
    describe_exit,
    isolated_config,
    judge,
    judge_setup,
)
from pmsm_hil.hil.runner.target_client import DutViolationError, TargetClient, TargetError
from pmsm_hil.hil.runner.target_console import TargetConsole
from pmsm_hil.hil.runner.target_time import TargetTime, target_time
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.links import Link, link_kind, open_link
from pmsm_hil.protocol.links.spawn_auth import spawn_auth
from pmsm_hil.protocol.links.wire_core import UdpEnd, link_end
from pmsm_hil.sim_target.process import LINK_STATS_LINE, READY_LINE, SPAWNED_IDLE_TIMEOUT_S

#: how long a spawned target may take to open its link (interpreter start and imports on a loaded machine)
SPAWN_READY_TIMEOUT_S = 60.0
#: how long the host waits for a UDP peer to agree a session
SESSION_TIMEOUT_S = 10.0


@dataclass(slots=True)
class TargetConnection:
    """The host's link and client, plus whatever runs the target (for closing)."""

    client: TargetClient
    host_link: Link
    target_link: Link | None = None
    process: subprocess.Popen[bytes] | None = None
    inproc_result: Callable[[], object] | None = None
    extra: list[Any] = field(default_factory=list)
    #: a spawned target's own link counters (its last stdout line), filled by `close`
    target_link_stats: dict[str, int] = field(default_factory=dict)
    #: target-specific metrics merged into metrics.json after the run (e.g. an emulated MCU's instruction
    #: counts); called once, after the loop, before `close`
    extra_metrics: Callable[[], dict[str, Any]] = field(default=lambda: {})
    #: names the target's part in the loop's ending (rewrites the outcome in place; a SIL target process that
    #: crashed or hung), called once after the loop, before the metrics
    ending: Callable[[LoopOutcome], None] | None = None
    #: wall time [s] a spawned target gets to exit after SIGTERM before SIGKILL
    stop_wait_s: float = 5.0
    #: a SIL target process's debug outputs (each step's torque reference), shared memory
    sil_debug: SilDebugSlot | None = None
    #: a spawned target's stdout and stderr, drained all the time (its console lines go to the run's log)
    console: TargetConsole | None = None
    #: the process that runs the target when it is not `process` (QEMU), 0: none
    other_pid: Callable[[], int] = field(default=lambda: 0)

    #: an emulated MCU's progress the loop reads in lockstep: (address of its running instruction count, virtual
    #: time of one instruction [ns]); (0, 0): none (the process's time counts)
    guest_progress: Callable[[], tuple[int, int]] = field(default=lambda: (0, 0))

    #: called by `close` before the target is stopped (QEMU: its console file into `console`)
    before_close: Callable[[], None] | None = None

    #: a board's outputs at the run's start, as the duties of the period before its first Command, from the
    #: machine's electrical angle [rad] and mechanical speed [rad/s] then (the virtual board: its open bridge while
    #: TIM1's outputs are off); None: the full-period zero vector (a target that answers from its first Measurement)
    first_duties: Callable[[float, float], tuple[float, ...]] | None = None
    #: a board: whether its Command answering a seq was sent with every gate off (the virtual board: TIM1's MOE = 0
    #: with its outputs released; that Command is the open bridge's duties, the wire having no form for it);
    #: None: the target's Commands are what it switches
    outputs_off: Callable[[int], bool] | None = None
    #: a board's per-period records since the last call (a BOARD_DTYPE block for /board/periods); None: none
    board_records: Callable[[], Any] | None = None

    def duties_at_start(self, sample: Any) -> tuple[float, ...]:
        """The duties of period 0 for the plant's state `sample` at the run's start (empty: the zero vector)."""
        if self.first_duties is None:
            return ()
        return self.first_duties(float(sample.theta_e), float(sample.omega_m))

    def target_pid(self) -> int:
        """The process the target runs in, which the loop observes for host stalls (a spawned `hil target`, a SIL
        target process, QEMU); 0: none the host can observe (in process, a board, an external target)."""
        if self.process is not None:
            return self.process.pid
        return self.other_pid()

    def own_time(self, timeout_s: float) -> TargetTime | None:
        """The target's own time for a wait of `timeout_s` (the safe stop's; `TargetTime`), None when the host
        observes no process of it (wall time)."""
        return target_time(self.target_pid(), timeout_s, self.guest_progress())

    def link_stats(self) -> dict[str, int]:
        """Host link counters plus decoder counters, plus how the native loop's receives waited (`blocked`,
        `spin_backoffs`, `spin_early_ends`: NativeWireLink.waits) on its links to another process, plus the
        configuration's resends (`config_resent`, `config_acks_repeated`: TargetClient)."""
        stats: dict[str, int] = {}
        for source in (self.host_link.stats, self.client.decoder.stats):
            for key, value in vars(source).items() if hasattr(source, "__dict__") else _slots(source):
                if isinstance(value, int):
                    stats[key] = stats.get(key, 0) + value
        stats.update(getattr(self.host_link, "waits", {}))
        stats.update(config_resent=self.client.config_resent, config_acks_repeated=self.client.config_acks_repeated)
        return stats

    def close(self) -> None:
        """Close links and stop a spawned target (reading its link counters)."""
        if self.before_close is not None:
            with contextlib.suppress(Exception):
                self.before_close()
            self.before_close = None
        if self.process is not None:
            _stop(self.process, self.stop_wait_s)
            if self.console is not None:
                self.console.join()
                self.target_link_stats = _target_link_stats(self.console.stats_line)
                text = self.console.stderr_text()
                if text and not self.console.verbose:  # what the target said (a warning, a crash) is not lost
                    print(text, file=sys.stderr)
        for link in (self.host_link, self.target_link):
            if link is not None:
                link.close()
        if self.sil_debug is not None:
            self.sil_debug.close()
        for item in self.extra:
            if isinstance(item, int):
                with contextlib.suppress(OSError):
                    os.close(item)
            elif isinstance(item, InterruptGuard):
                item.disarm()
            elif callable(getattr(item, "close", None)):  # a QEMU target: stopped on every exit path
                item.close()


def _stop(proc: subprocess.Popen[bytes], wait_s: float = 5.0) -> None:
    if proc.poll() is None:
        proc.terminate()
    try:
        proc.wait(timeout=wait_s)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def _target_link_stats(line: str) -> dict[str, int]:
    """The counters of a stopped `hil target`'s last "link stats:" line ({} if it printed none)."""
    with contextlib.suppress(ValueError):
        stats = json.loads(line) if line else {}
        return {str(k): int(v) for k, v in stats.items()} if isinstance(stats, dict) else {}
    return {}


def _spawn_target(spec: str, native: bool = False, sil: str | None = None,
                  pass_fds: tuple[int, ...] = (), key: bytes | None = None,
                  sil_debug: SilDebugSlot | None = None,
                  rt_priority: int = 0, spin_us: float | None = None,
                  verbose: bool = False) -> tuple[subprocess.Popen[bytes], TargetConsole]:
    """Start `hil target` (`--native`: its C serve loop; `sil`: serving that SIL library, in its own process
    group so a terminal's Ctrl-C reaches the runner only, which stops it in order) on `spec` and wait for its
    ready line; raises TargetError with its own error line if it exits first (a port in use, a bad library) or
    does not get ready in time. Its stdout and stderr are drained all the time by the returned console
    (`verbose`: its lines on the terminal too). `key`: the frames' authentication key,
    written to its stdin (`--auth-key-stdin`: never on its command line, which any user may read). `sil_debug`:
    the memory where a SIL target's serve loop puts each step's torque reference (`--sil-debug-fd`); `spin_us`:
    its receives' busy-poll (`--spin-us`, None: its default)."""
    if sil_debug is not None:
        pass_fds = (*pass_fds, sil_debug.fd)
    cmd = [sys.executable, "-m", "pmsm_hil.app.cli.main", "target", "--link", spec, "--role", "target",
           "--parent-pid", str(os.getpid()), "--idle-timeout", repr(SPAWNED_IDLE_TIMEOUT_S), *(["--native"] * native),
           *(["--sil", sil] if sil is not None else []), *(["--auth-key-stdin"] if key is not None else []),
           *(["--sil-debug-fd", str(sil_debug.fd)] if sil_debug is not None else []),
           *(["--rt-priority", str(rt_priority)] if rt_priority else []),  # the C serve loop at SCHED_FIFO
           *(["--spin-us", f"{spin_us:g}"] if spin_us is not None else [])]
    # its own session: a terminal's Ctrl-C (or a SIGTERM to the run's process group) reaches the run, which
    # stops the loop, sends the disabling Setpoint and then stops the target (`_stop`), not the target first
    proc = subprocess.Popen(cmd, env=dict(os.environ), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            pass_fds=pass_fds, start_new_session=True,
                            stdin=subprocess.PIPE if key is not None else None)
    console = TargetConsole(proc.stdout, proc.stderr, ready_prefix=READY_LINE, stats_prefix=LINK_STATS_LINE,
                            verbose=verbose)
    if proc.stdin is not None and key is not None:
        with proc.stdin, contextlib.suppress(OSError):  # a target that died at once is told below
            proc.stdin.write(key.hex().encode("ascii") + b"\n")
    if console.wait_ready(SPAWN_READY_TIMEOUT_S):
        return proc, console
    _stop(proc)
    console.join()
    why = console.stderr_text().splitlines()
    if why:
        detail = why[-1].removeprefix("hil: error: ")
    elif proc.returncode in (-15, -9):
        detail = f"no '{READY_LINE}' line within {SPAWN_READY_TIMEOUT_S:g} s"
    elif proc.returncode < 0:  # e.g. a SIL library whose hil_app_init crashed
        detail = f"killed by {describe_exit(proc.returncode)}"
    else:
        detail = f"exit code {proc.returncode}"
    who = f"SIL target process for {sil}" if sil is not None else f"spawned target on {spec!r}"
    raise TargetError(f"{who} did not start: {detail}")


def _await_session(link: Link) -> None:
    """Agree the session of a UDP link with its peer before the run (LinkError naming the peer if none)."""
    end = link_end(link)
    if isinstance(end, UdpEnd):
        end.wait_session(SESSION_TIMEOUT_S)


def _slots(obj: object) -> list[tuple[str, object]]:
    names: list[str] = []
    for cls in type(obj).__mro__:
        names += list(getattr(cls, "__slots__", ()))
    return [(n, getattr(obj, n)) for n in names if hasattr(obj, n)]


def _sil_library(path: str) -> str:
    """A SIL library path; a source folder is built for the host first (`hil fw build --board host`)."""
    from pmsm_hil.sim_target.fw_build import build_firmware

    p = Path(path).expanduser()
    if p.is_dir():
        return str(build_firmware("host", p).path)
    return str(p)


#: real time over a link: a spawned native target spins for frames only with at least this many CPUs (the loop's,
#: the target's, one for the rest: the drain, the logger, the system); below it blocks
REALTIME_SPIN_MIN_CPUS = 3


def realtime_target_spin_us(cfg: RunConfig, native: bool) -> float | None:
    """How long the spawned target busy-polls for a frame [µs] (None: its default). In real time on a machine
    with fewer than `REALTIME_SPIN_MIN_CPUS` CPUs it blocks (0): a SCHED_FIFO target spinning the whole period
    keeps the run's drain and logger off the only other CPU, the loop's ring fills and periods start ms late
    (docs/benchmarks.md); blocked, it wakes in ~5 µs while the run holds the CPUs' wake-up latency
    (`--cpu-dma-latency`, pm_qos.py)."""
    if not native or cfg.mode != "realtime" or realtime_target_may_spin():
        return None
    return 0.0


def realtime_target_may_spin() -> bool:
    """A real-time run's native target may spin for its frames: this process may run on at least
    `REALTIME_SPIN_MIN_CPUS` CPUs."""
    return len(os.sched_getaffinity(0)) >= REALTIME_SPIN_MIN_CPUS


def _connect_spawned(cfg: RunConfig, codec: FrameCodec, native: bool, sil: str | None = None,
                     sil_debug: SilDebugSlot | None = None) -> TargetConnection:
    """A `hil target` process on the mirror of the run's link (`sil`: serving that SIL library)."""
    spec = cfg.link_spec
    specs = link_kind(spec).mirror(cfg.link, spec)
    specs, key = spawn_auth(specs)  # authenticated frames by default (src/pmsm_hil/protocol/links/auth.py)
    host_link = open_link(specs.host, "host")
    conn = TargetConnection(TargetClient(host_link, codec), host_link, extra=list(specs.keep_open))
    try:
        rt = cfg.rt_priority if native and cfg.mode == "realtime" else 0  # the pair at the same priority
        conn.process, conn.console = _spawn_target(specs.target, native, sil, key=key, sil_debug=sil_debug,
                                                   rt_priority=rt, spin_us=realtime_target_spin_us(cfg, native),
                                                   verbose=cfg.verbose)
        _await_session(host_link)
    except BaseException:
        conn.close()
        raise
    return conn


def _connect_sil_process(cfg: RunConfig, library: str) -> TargetConnection:
    """The SIL firmware served by its own process (`hil target --native --sil`); its crash or hang is told
    in the ending (sil_watch.judge) and a hung one is killed."""
    from pmsm_hil.sim_target.sil import SilError

    if not Path(library).is_file():
        raise SilError(f"SIL library {library} not found (build one with `hil fw build --board host`)")
    cfg = isolated_config(cfg)
    spec = cfg.link_spec
    codec = FrameCodec(link_kind(spec).profile(spec))
    debug = SilDebugSlot()  # the torque reference of each step, which no frame carries
    try:
        if cfg.link == SOCKETPAIR_LINK:
            conn = _connect_socketpair(codec, library, debug, verbose=cfg.verbose)
        else:
            conn = _connect_spawned(cfg, codec, True, library, debug)
    except BaseException:
        debug.close()
        raise
    debug.close_fd()  # the target process holds it now
    conn.sil_debug = debug
    conn.stop_wait_s = SIL_STOP_WAIT_S
    proc = conn.process
    assert proc is not None
    guard = InterruptGuard(proc)
    guard.arm()
    conn.extra.insert(0, guard)  # disarmed first on close

    console = conn.console
    busy = BusyWatch(proc.pid, cfg.step_timeout_s)
    hung_in: list[str] = []

    def initialised() -> bool:
        return console is None or console.initialised.is_set()

    def ending(out: LoopOutcome) -> None:
        if console is not None and proc.poll() is not None:
            console.join(0.5)  # every line it wrote read (its "sil initialised" line)
        hung = judge_setup(proc, out, hung_in[0] if hung_in else None, initialised(), cfg.step_timeout_s)
        if hung or judge(proc, out, cfg.step_timeout_s, realtime=cfg.mode == "realtime"):
            proc.kill()

    def pump() -> None:  # waits of the client (configuration, safe stop, the Python loop) end on its death
        if proc.poll() is not None:
            raise DutViolationError(f"the SIL target process ended ({describe_exit(proc.returncode)})")
        if busy.hung():  # computing all along without answering: hung in its set-up (or in a step)
            hung_in[:] = ["hil_app_config" if initialised() else "hil_app_init"]
            raise DutViolationError(f"the SIL target process is hung in {hung_in[0]}")

    conn.ending = ending
    conn.client.pump = pump
    return conn


def _connect_socketpair(codec: FrameCodec, library: str, sil_debug: SilDebugSlot | None = None, *,
                        verbose: bool = False) -> TargetConnection:
    """The SIL target process on one end of a Unix socket pair (serial framing), the host's link on the other."""
    host_end, target_end = socket.socketpair()
    host_fd, target_fd = host_end.detach(), target_end.detach()
    try:
        host_link = open_link(f"serial:fd:{host_fd}", "host")
    except BaseException:
        os.close(host_fd)
        os.close(target_fd)
        raise
    conn = TargetConnection(TargetClient(host_link, codec), host_link)
    try:
        conn.process, conn.console = _spawn_target(f"serial:fd:{target_fd}", True, library, (target_fd,),
                                                   sil_debug=sil_debug, verbose=verbose)
    except BaseException:
        conn.close()
        raise
    finally:
        os.close(target_fd)  # the target's end only in the target: its death is the host's end of file
    return conn


def _connect_sil(cfg: RunConfig, codec: FrameCodec, path: str) -> TargetConnection:
    """The SIL firmware in its own process (default), or in this process behind both ends of the run's link
    (`--sil-in-process`, like the in-process target: unprotected)."""
    from pmsm_hil.sim_target.sil import SilTarget

    library = _sil_library(path)
    if not cfg.sil_in_process:
        return _connect_sil_process(cfg, library)
    target_link = open_link(cfg.link, "target")
    try:
        host_link = open_link(cfg.link, "host")
    except BaseException:
        target_link.close()
        raise
    try:
        target = SilTarget(target_link, library)
    except BaseException:
        target_link.close()
        host_link.close()
        raise
    client = TargetClient(host_link, codec, pump=target.service)
    return TargetConnection(client, host_link, target_link=target_link, inproc_result=target.last_result,
                            extra=[target.firmware])


def _connect_qemu(cfg: RunConfig, path: str) -> TargetConnection:
    """QEMU running the ELF; the host's serial link on its UART socket; instruction counts as extra metrics
    over the metrics window (the firmware steps once per period from the first, enabled, period on)."""
    from pmsm_hil.sim_target.qemu import QemuTarget

    skip = round(cfg.scenario.settle_s / cfg.ts_s)
    transport = "mailbox" if cfg.link == QEMU_MAILBOX_LINK else "uart"
    qemu = QemuTarget(Path(path).expanduser(), mcu_clock_hz=cfg.mcu_clock_hz, skip_steps=skip, transport=transport)
    try:
        host_link: Link = qemu.mailbox_link() if transport == "mailbox" else open_link(qemu.link_spec, "host")
    except BaseException:
        qemu.close()
        raise
    from pmsm_hil.hil.runner.qemu_ending import judge_qemu

    codec = FrameCodec("canfd")  # both transports carry the CAN FD layouts, as the serial link does
    console = TargetConsole(None, None, ready_prefix=READY_LINE, stats_prefix=LINK_STATS_LINE, verbose=cfg.verbose)
    return TargetConnection(TargetClient(host_link, codec), host_link, extra=[qemu], extra_metrics=qemu.metrics,
                            ending=lambda out: judge_qemu(qemu, out, cfg.lockstep_timeout_s),
                            other_pid=lambda: qemu.process.pid if qemu.process is not None else 0,
                            guest_progress=lambda: (qemu.progress_address(), qemu.ns_per_instruction),
                            console=console, before_close=lambda: console.feed(qemu.console_text()))


def _connect_board(cfg: RunConfig, path: str) -> TargetConnection:
    """The ELF on the virtual STM32G4 board in this process; the board object is the host's link (each Measurement
    runs one period of the firmware); its metrics (handlers, CPU load, late compares) join metrics.json."""
    from pmsm_hil.hil.runner.board_ending import judge_board
    from pmsm_hil.hil.runner.board_log import BoardLog
    from pmsm_hil.sim_target.stm32g4.board_file import load_board
    from pmsm_hil.sim_target.stm32g4.frame_link import is_core_image
    from pmsm_hil.sim_target.stm32g4.link import BoardLink

    elf = Path(path).expanduser()
    if not elf.is_file():
        from pmsm_hil.sim_target.stm32g4.peripherals.base import BoardError

        raise BoardError(f"stm32g4 target: {elf} not found")
    console = TargetConsole(None, None, ready_prefix=READY_LINE, stats_prefix=LINK_STATS_LINE, verbose=cfg.verbose)
    lines: list[str] = []
    if is_core_image(elf):
        return _connect_core_image(cfg, elf, console, lines)
    link = BoardLink(elf, load_board(cfg.board), ts_s=cfg.ts_s, pole_pairs=int(cfg.motor.pole_pairs),
                     psi_f_wb=float(getattr(cfg.motor, "psi_f", 0.0)), vdc_v=float(cfg.motor.vdc),
                     skip_periods=round(cfg.scenario.settle_s / cfg.ts_s), can_bitrates=_link_bitrates(cfg),
                     console=lambda source, line: lines.append(f"{source}: {line}"))
    codec = FrameCodec("canfd")
    return TargetConnection(TargetClient(link, codec), link, extra_metrics=link.metrics, console=console,
                            ending=lambda out: judge_board(link, out),
                            before_close=lambda: console.feed("\n".join(lines)), first_duties=link.first_duties,
                            outputs_off=link.outputs_off, board_records=BoardLog(link, cfg.ts_s).take)


def _link_bitrates(cfg: RunConfig) -> tuple[int | None, int | None]:
    """The CAN bit rates the run's --link states (`bitrate=`, `data_bitrate=` [bit/s]; None where not stated): a
    firmware on the virtual board whose FDCAN1 bit timing differs ends the run naming NBTP/DBTP."""
    from pmsm_hil.protocol.links.spec import parse_spec

    options = parse_spec(cfg.link).options
    nominal, data = options.get("bitrate"), options.get("data_bitrate")
    return (nominal if isinstance(nominal, int) else None, data if isinstance(data, int) else None)


def _connect_core_image(cfg: RunConfig, elf: Path, console: TargetConsole, lines: list[str]) -> TargetConnection:
    """A firmware-API image (`hil fw build --board stm32g474 --src DIR`) on the virtual board: the frames go over
    its FDCAN1, in CAN FD frames when the firmware enabled FD operation, else classic ones."""
    from pmsm_hil.hil.runner.board_ending import judge_board
    from pmsm_hil.sim_target.stm32g4.board_file import load_board
    from pmsm_hil.sim_target.stm32g4.frame_link import FrameBoardLink

    link = FrameBoardLink(elf, load_board(cfg.board), ts_s=cfg.ts_s,
                          skip_periods=round(cfg.scenario.settle_s / cfg.ts_s), can_bitrates=_link_bitrates(cfg),
                          console=lambda source, line: lines.append(f"{source}: {line}"))
    codec = FrameCodec(link.profile)
    return TargetConnection(TargetClient(link, codec), link, extra_metrics=link.metrics, console=console,
                            ending=lambda out: judge_board(link, out),
                            before_close=lambda: console.feed("\n".join(lines)))


def connect_target(cfg: RunConfig, *, silent_after: int | None = None, native_target: bool = False) -> TargetConnection:
    """Open the link(s) and, for in-process or spawned targets, start the target (`native_target`: a spawned
    target runs its C serve loop, `hil target --native`)."""
    if cfg.target.startswith("qemu:") and cfg.target_path is not None:
        return _connect_qemu(cfg, cfg.target_path)
    if cfg.target.startswith("stm32g4:") and cfg.target_path is not None:
        return _connect_board(cfg, cfg.target_path)
    spec = cfg.link_spec
    link = link_kind(spec)
    kind = link.auto_target(spec) if cfg.target == "auto" else cfg.target
    codec = FrameCodec(link.profile(spec))
    if cfg.target.startswith("sil:") and cfg.target_path is not None:
        return _connect_sil(cfg, codec, cfg.target_path)
    if kind == "inproc":
        from pmsm_hil.sim_target.target import SimTarget

        host_spec = target_spec = cfg.link
        if spec.kind == "udp" and spec.channel is None:  # both ends here: two ports free now, not the fixed
            mirrored = link.mirror(cfg.link, spec)  # defaults another run or target on this machine may hold
            host_spec, target_spec = mirrored.host, mirrored.target
        target_link = open_link(target_spec, "target")
        host_link = open_link(host_spec, "host")
        target = SimTarget(target_link, codec, silent_after=silent_after)
        client = TargetClient(host_link, codec, pump=target.service)
        return TargetConnection(client, host_link, target_link=target_link,
                                inproc_result=lambda: target.last_result, extra=[target])
    if kind == "spawn":
        return _connect_spawned(cfg, codec, native_target)
    host_link = open_link(cfg.link, "host")
    conn = TargetConnection(TargetClient(host_link, codec), host_link)
    try:
        _await_session(host_link)
    except BaseException:
        conn.close()
        raise
    return conn
