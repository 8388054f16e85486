"""`hil bench loop`: closed-loop periods per second (lockstep, logging off/on, cross-process) and
real-time lateness; medians over repeats because this machine is shared and noisy."""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pmsm_hil.app.cli.parsing import non_negative_int, positive_float
from pmsm_hil.app.cli.run_options_cli import add_option
from pmsm_hil.errors import HilError
from pmsm_hil.hil.atomic_write import write_text_atomic
from pmsm_hil.hil.runner.contract import EndCode
from pmsm_hil.hil.runner.option_values import coerce
from pmsm_hil.hil.runner.reference_loop import reference_loop
from pmsm_hil.hil.runner.run_options import DEFAULTS, OPTIONS

if TYPE_CHECKING:  # the runner (numpy, python-can) is imported where a bench runs, not for its parser
    from pmsm_hil.hil.runner.run_config import RunConfig

#: how an error names a value of the bench's own run (not an option of the command line)
BENCH_SOURCES = {"motor": "hil bench", "controller": "hil bench", "loop": "hil bench", "settle": "hil bench",
                 "no_log": "hil bench", "speed": "hil bench", "load": "hil bench", "board": "hil bench"}
#: the operating point of `--board`'s closed loop (the example firmware's: examples/stm32g4_foc) [rpm], [N·m]
BOARD_SPEED_RPM = 1500.0
BOARD_LOAD_NM = 7.0


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `hil bench loop`."""
    p = subparsers.add_parser("loop", help="closed-loop periods per second and real-time lateness")
    p.add_argument("--duration", type=positive_float("--duration"), default=0.5,
                   help="simulated seconds per measurement (default 0.5)")
    p.add_argument("--repeats", type=non_negative_int("--repeats"), default=3, help="repeats (median)")
    add_option(p, OPTIONS["ts"], help="control period [s] of every measured run (default 100e-6; e.g. 25e-6 for "
                                      "40 kHz)")
    p.add_argument("--cross-process", default="udp,serial,pycan",
                   help="comma list of cross-process links to measure (udp, serial, pycan, socketcan; empty: none): "
                        "the Python "
                        "pair, then the native pair (native loop + `hil target --native`) beside the Python pair, "
                        "idle and beside a CPU burner; for udp also the floor: a bare C ping-pong between two "
                        "processes, spinning and blocking, idle and beside the burner (udp_floor_*); pycan: the "
                        "host's end opened as a python-can adapter (the hiludp interface) to the native target, "
                        "both loops (the C loop through its callback link); socketcan: python-can's socketcan "
                        f"interface on {SOCKETCAN_BENCH_SPEC} (needs that interface: CI's vcan VM) to the native "
                        "target, both loops (the C loop through its native SocketCAN wire)")
    p.add_argument("--no-realtime", action="store_true", help="skip the real-time lateness measurement")
    p.add_argument("--qemu", type=Path, metavar="ELF",
                   help="also measure a firmware for mps2-an386 in QEMU (hil fw build --board mps2-an386) over its "
                        "UART and its PSRAM mailbox (lockstep_qemu_uart_hz, lockstep_qemu_mailbox_hz)")
    p.add_argument("--board", nargs=2, metavar=("KIND", "ELF"),
                   help="also measure a firmware on a virtual board (KIND stm32g4: an STM32G4 ELF whose TIM1 carrier "
                        "period is --ts and that runs its own controller): the board alone, fed Measurements "
                        "(lockstep_stm32g4_board_only_hz; per CPU second of the bench: _cpu_hz), and the closed "
                        "loop with --controller external at "
                        f"{BOARD_SPEED_RPM:g} rpm / {BOARD_LOAD_NM:g} N·m (lockstep_stm32g4_hz; no figure for a run "
                        "that did not complete: lockstep_stm32g4_error says how it ended), medians over --repeats, "
                        "beside --qemu's figures when both are given")
    p.add_argument("--board-file", metavar="NAME_OR_FILE",
                   help="the board description of --board's firmware (a bundled name or a TOML file; default the "
                        "bundled default; examples/stm32g4_foc/board.toml for the example firmware)")
    add_option(p, OPTIONS["load_fmu"],
               help="also measure the native loop with this load FMU (FMI 2/3 Co-Simulation, inputs speed, output "
                    "torque; logging off): in its own process (lockstep_inproc_native_load_fmu_hz, the default) and "
                    "in the run's (lockstep_inproc_native_load_fmu_unisolated_hz), load_fmu_isolation_cost_pct their "
                    "ratio in the same run")
    p.add_argument("--json", type=Path, help="write the figures as JSON")
    p.set_defaults(func=run)


def _base(duration: float, ts: float = 100e-6, loop: str = "python", **options: Any) -> RunConfig:
    """The measured run: niu2020 IPMSM, MPCC, steady without settling, `duration` [s], control period `ts` [s],
    the `loop` (the Python reference loop: the native loop's figures are put beside it), further run `options`."""
    from pmsm_hil.hil.runner.run_config import RunConfig

    return RunConfig.from_options({"motor": "niu2020-ipmsm", "controller": "mpcc", "loop": loop, "ts": ts,
                                   "settle": 0.0, "duration": duration, "no_log": True, **options}, BENCH_SOURCES)


def _log_off_and_on(cfg: RunConfig, repeats: int,
                    stage: Callable[[str], None]) -> tuple[dict[str, Any], dict[str, Any]]:
    """`_median_rate` of `cfg` with logging off, then on (each logged run into a fresh folder); `stage` is told
    "logging off" / "logging on" before each."""
    stage("logging off")
    off = _median_rate(lambda: cfg, repeats)
    stage("logging on")
    with tempfile.TemporaryDirectory() as tmp:
        counter = iter(range(1000))
        on = _median_rate(lambda: replace(cfg, out_dir=Path(tmp) / f"run{next(counter)}"), repeats)
    return off, on


def _median_rate(make: Callable[[], RunConfig], repeats: int, exclude_safe_stop: bool = False) -> dict[str, Any]:
    from pmsm_hil.hil.runlog.reader import read_periods
    from pmsm_hil.hil.runner.run import run_closed_loop

    rates: list[float] = []
    extra: dict[str, Any] = {}
    ring_waits = 0
    logged_all = True
    for _ in range(max(repeats, 1)):
        res = run_closed_loop(make())
        excluded = (res.metrics.get("safe_stop_wait_ms") or 0.0) / 1e3 if exclude_safe_stop else 0.0
        rates.append(res.outcome.completed_periods / (res.outcome.wall_time_s - excluded))
        extra = res.metrics
        ring_waits += res.outcome.ring_waits
        if res.mcap_path is not None:
            logged_all = logged_all and len(read_periods(res.mcap_path)) == res.outcome.completed_periods
    return {"periods_per_s": statistics.median(rates), "runs": rates, "last_metrics": extra,
            "ring_waits": ring_waits, "logged_all": logged_all}


@contextlib.contextmanager
def _cpu_burner() -> Iterator[int]:
    """A process spinning on a CPU (`while True: pass`) for the block: load on the other core; yields its pid."""
    proc = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(0.2)  # running before the measurement starts
        yield proc.pid
    finally:
        proc.kill()
        proc.wait()


def _native_pair_under_load(base: RunConfig, name: str, spec: str, repeats: int, runs: str,
                            progress: Callable[[str], None]) -> dict[str, Any]:
    """The native loop with the native target over link `spec` (udp, serial:pty) and the Python pair, idle and
    beside a CPU burner, in this run: the rates (the wait for the confirmation of the disabling Setpoint
    excluded, as in both loops) as lockstep_{name}_native_hz / lockstep_{name}_python_hz (+ _loaded) and the
    loaded / idle ratios."""
    out: dict[str, Any] = {}
    pairs = tuple((key, cfg) for key, cfg in (
        (f"{name}_native", replace(base, link=spec, target="spawn", loop="native")),
        (f"{name}_python", replace(base, link=spec, target="spawn", loop="python")))
        if cfg.loop == "native" or reference_loop() is not None)
    for load in ("", "_loaded"):
        for key, cfg in pairs:
            progress(f"lockstep over {spec}, {key.partition('_')[2]} pair{', a CPU burner beside it' if load else ''} "
                     f"({runs})")
            try:
                def make(cfg: RunConfig = cfg) -> RunConfig:
                    return cfg

                with _cpu_burner() if load else contextlib.nullcontext():
                    res = _median_rate(make, repeats, exclude_safe_stop=True)
                out[f"lockstep_{key}{load}_hz"] = res["periods_per_s"]
            except Exception as exc:
                out[f"lockstep_{key}{load}_error"] = str(exc)
    for key, _ in pairs:
        idle, loaded = out.get(f"lockstep_{key}_hz"), out.get(f"lockstep_{key}_loaded_hz")
        if idle and loaded:
            out[f"{key}_load_ratio"] = loaded / idle
    return out


#: cross-process links measured as a python-can adapter to the native target (`_adapter_pair`)
ADAPTER_PAIRS = ("pycan", "socketcan")
#: `--cross-process socketcan`: python-can's socketcan interface on this CAN FD interface (a vcan in CI's VM)
SOCKETCAN_BENCH_SPEC = "socketcan:vcan0,fd=true"


def _adapter_pair(base: RunConfig, name: str, repeats: int, runs: str,
                  progress: Callable[[str], None]) -> dict[str, Any]:
    """A python-can adapter to a fast target, both loops in this run (lockstep_{name}_{python,native}_hz and
    {name}_native_speedup); the other end is the native target (`hil target --native`, started here).
    pycan: the host opens `hiludp` the way python-can opens any adapter whose I/O is a Python library (not a
    registered link kind: the C loop drives it through its callback link). socketcan: python-can's socketcan
    interface (`SOCKETCAN_BENCH_SPEC`; Linux's route to PEAK, Kvaser, gs_usb, ... adapters), which the C loop
    drives through its native SocketCAN wire."""
    from pmsm_hil.protocol.links.wire_core import free_udp_ports

    if name == "pycan":
        host, target = free_udp_ports(2)
        host_spec, target_spec = f"hiludp:{host}:{target}", f"udp:{target}:{host}"
        what = "a python-can adapter (hiludp)"
    else:
        host_spec = target_spec = SOCKETCAN_BENCH_SPEC
        what = f"python-can's socketcan interface ({SOCKETCAN_BENCH_SPEC})"
    proc = subprocess.Popen([sys.executable, "-m", "pmsm_hil.app.cli.main", "target", "--native", "--link",
                             target_spec], stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    out: dict[str, Any] = {}
    try:
        if proc.stdout is None or not proc.stdout.readline().startswith(b"ready"):
            why = proc.stderr.read().decode(errors="replace").strip().splitlines()[-1:] if proc.stderr else []
            return {f"lockstep_{name}_error": f"the native target did not start on {target_spec}"
                                              + (f": {why[0]}" if why else "")}
        for loop in ("python", "native") if reference_loop() is not None else ("native",):
            progress(f"lockstep over {what} to the native target, {loop} loop ({runs})")
            cfg = replace(base, link=host_spec, target="external", loop=loop)

            def make(cfg: RunConfig = cfg) -> RunConfig:
                return cfg

            try:
                out[f"lockstep_{name}_{loop}_hz"] = _median_rate(make, repeats)["periods_per_s"]
            except Exception as exc:
                out[f"lockstep_{name}_{loop}_error"] = str(exc)
    finally:
        proc.terminate()
        proc.wait(timeout=10)
    if out.get(f"lockstep_{name}_python_hz") and out.get(f"lockstep_{name}_native_hz"):
        out[f"{name}_native_speedup"] = out[f"lockstep_{name}_native_hz"] / out[f"lockstep_{name}_python_hz"]
    return out


def _udp_floor(progress: Callable[[str], None], round_trips: int = 5000) -> dict[str, float]:
    """The floor of the UDP pair on this machine (src/pmsm_hil/hil/runner/c/links/link_floor.c): mean round trip [µs] of
    a bare C ping-pong between two processes spinning (as the native links do) or always blocking, idle and beside a CPU
    burner; `udp_floor_load_ratio` is the best rate beside the burner over the best idle rate - the most the
    native pair's `udp_native_load_ratio` can reach here."""
    from pmsm_hil.hil.runner.core_link import native_lib
    from pmsm_hil.hil.runner.wire import SPIN_NS

    ffi, lib = native_lib()
    result = ffi.new("nl_udp_floor_t *")
    out: dict[str, float] = {}
    for load in ("", "_loaded"):
        progress(f"udp floor: bare C ping-pong between two processes{', a CPU burner beside it' if load else ''}")
        with _cpu_burner() if load else contextlib.nullcontext():
            for mode, spin in (("spin", SPIN_NS), ("block", 0)):
                err = int(lib.nl_udp_floor(round_trips, spin, result))
                if err:
                    raise OSError(err, f"udp floor ({mode}{load}): {os.strerror(err)}")
                out[f"udp_floor_{mode}{load}_us"] = int(result.mean_ns) / 1e3
    best_idle = min(out["udp_floor_spin_us"], out["udp_floor_block_us"])
    best_loaded = min(out["udp_floor_spin_loaded_us"], out["udp_floor_block_loaded_us"])
    out["udp_floor_load_ratio"] = best_idle / best_loaded
    return out


def measure(duration: float, repeats: int, cross: list[str], realtime: bool,
            progress: Callable[[str], None] = lambda _msg: None, qemu: Path | None = None,
            load_fmu: Path | None = None, ts: float = 100e-6, board: Path | None = None,
            board_file: str | None = None) -> dict[str, Any]:
    """All loop figures; keys documented in docs/benchmarks.md. `progress` gets one line per stage. The Python
    loop's rows (and the native/python ratios) need the test suite's reference loop (tests/oracle; not part of
    the product): without it they are left out and `python_loop` says so."""
    from pmsm_hil.app.bench.logger_limit import logger_limit
    from pmsm_hil.hil.runner.run import run_closed_loop

    python = reference_loop() is not None
    base = _base(duration, ts, "python" if python else "native")
    out: dict[str, Any] = {"duration_s": duration, "repeats": repeats, "ts_s": ts}
    runs = f"{max(repeats, 1)} × {duration:g} s"
    if python:
        off, on = _log_off_and_on(base, repeats, lambda what: progress(f"lockstep in-process, {what} ({runs})"))
        out["lockstep_inproc_log_off_hz"] = off["periods_per_s"]
        out["lockstep_inproc_log_on_hz"] = on["periods_per_s"]
        out["logging_cost_pct"] = 100.0 * (1.0 - on["periods_per_s"] / off["periods_per_s"])
    else:
        out["python_loop"] = "left out: the Python loop is the test suite's reference (tests/oracle), not the product's"
    native = replace(base, loop="native")
    n_off, n_on = _log_off_and_on(native, repeats,
                                  lambda what: progress(f"lockstep in-process, native loop (C), {what} ({runs})"))
    out["lockstep_inproc_native_log_off_hz"] = n_off["periods_per_s"]
    out["lockstep_inproc_native_log_on_hz"] = n_on["periods_per_s"]
    out["inproc_native_log_on_ring_waits"] = n_on["ring_waits"]
    out["inproc_native_log_on_every_period_logged"] = n_on["logged_all"]
    progress("the run logger's limit: period records and their frames fed to it as fast as it takes them")
    limit = logger_limit()
    out["logger_limit_hz"] = limit.periods_per_s
    out["logger_limit_stall_s"] = limit.stall_s
    if load_fmu is not None:
        progress(f"lockstep in-process, native loop (C), load FMU {load_fmu.name} in its own process, logging off "
                 f"({runs})")
        with_fmu = _base(duration, ts, "native", load_fmu=load_fmu)
        n_fmu = _median_rate(lambda: with_fmu, repeats)
        progress(f"the same, the load FMU in the run's process (--load-fmu-isolation none) ({runs})")
        fmu_inproc = _base(duration, ts, "native", load_fmu=load_fmu, load_fmu_isolation="none")
        n_fmu_inproc = _median_rate(lambda: fmu_inproc, repeats)
        out["lockstep_inproc_native_load_fmu_hz"] = n_fmu["periods_per_s"]
        out["lockstep_inproc_native_load_fmu_unisolated_hz"] = n_fmu_inproc["periods_per_s"]
        out["load_fmu_cost_pct"] = 100.0 * (1.0 - n_fmu["periods_per_s"] / n_off["periods_per_s"])
        out["load_fmu_isolation_cost_pct"] = 100.0 * (1.0 - n_fmu["periods_per_s"] / n_fmu_inproc["periods_per_s"])
    if python:
        out["native_speedup_log_off"] = n_off["periods_per_s"] / off["periods_per_s"]
        out["native_speedup_log_on"] = n_on["periods_per_s"] / on["periods_per_s"]
    from pmsm_hil.dashboards.bench import live_rerun_rate

    progress(f"lockstep in-process, live Rerun dashboard to an .rrd ({runs})")
    rerun = live_rerun_rate(base, repeats)
    out["lockstep_inproc_rerun_on_hz"] = rerun["periods_per_s"]
    out["rerun_cost_pct"] = 100.0 * (1.0 - rerun["periods_per_s"] / (off if python else n_off)["periods_per_s"])
    for name in [c for c in cross if c not in ADAPTER_PAIRS]:
        spec = {"udp": "udp", "serial": "serial:pty"}.get(name, name)
        def make(spec: str = spec) -> RunConfig:
            return replace(base, link=spec, target="spawn")

        progress(f"lockstep, target in its own process over {spec} ({runs})")
        try:
            res = _median_rate(make, repeats)
            out[f"lockstep_{name}_process_hz"] = res["periods_per_s"]
        except Exception as exc:
            out[f"lockstep_{name}_process_error"] = str(exc)
    for name, spec in (("udp", "udp"), ("serial", "serial:pty")):
        if name in cross:  # the native pair beside the Python pair (both spawned)
            out.update(_native_pair_under_load(base, name, spec, repeats, runs, progress))
    for name in [c for c in cross if c in ADAPTER_PAIRS]:
        out.update(_adapter_pair(base, name, repeats, runs, progress))
    if "udp" in cross:
        try:
            out.update(_udp_floor(progress))
        except OSError as exc:
            out["udp_floor_error"] = str(exc)
    if board is not None:
        out.update(_board_rates(board, board_file, ts, duration, repeats, runs, progress))
    if qemu is not None:
        for transport, link in (("uart", "virtual"), ("mailbox", "mailbox")):
            progress(f"lockstep, {qemu.name} in QEMU mps2-an386 over its {transport} ({runs})")
            def make_qemu(link: str = link) -> RunConfig:
                return replace(base, target=f"qemu:{qemu}", link=link)

            try:
                res = _median_rate(make_qemu, repeats)
                out[f"lockstep_qemu_{transport}_hz"] = res["periods_per_s"]
            except Exception as exc:
                out[f"lockstep_qemu_{transport}_error"] = str(exc)
    if realtime:
        khz = f"{1e-3 / ts:g}khz"
        progress(f"real time in-process at {khz} ({duration:g} s)")
        rt = run_closed_loop(replace(base, mode="realtime"))
        out[f"realtime_inproc_{khz}_lateness_us"] = rt.metrics.get("lateness_us")
        out[f"realtime_inproc_{khz}_deadline_misses"] = rt.metrics.get("deadline_misses")
    return out


def _board_rates(elf: Path, board_file: str | None, ts: float, duration: float, repeats: int, runs: str,
                 progress: Callable[[str], None]) -> dict[str, Any]:
    """The virtual STM32G4 board's figures: the board alone (`_board_only_rate`) and the closed loop, the firmware
    as the controller (`--controller external`) at the example's operating point, each the median over `repeats`.
    A closed-loop run that does not complete gives no figure: lockstep_stm32g4_error names its ending."""
    from pmsm_hil.hil.runner.run import run_closed_loop

    out: dict[str, Any] = {}
    progress(f"lockstep, {elf.name} alone on the virtual STM32G4 board, fed Measurements ({runs})")
    try:
        alone = [_board_only_rate(elf, ts, duration, board_file) for _ in range(max(repeats, 1))]
    except HilError as exc:  # a firmware the board cannot run: said, the other figures kept
        return {"lockstep_stm32g4_error": str(exc)}
    out["lockstep_stm32g4_board_only_hz"] = statistics.median(wall for wall, _ in alone)
    out["lockstep_stm32g4_board_only_cpu_hz"] = statistics.median(cpu for _, cpu in alone)
    progress(f"lockstep, {elf.name} on the virtual STM32G4 board, closed loop ({runs})")
    options: dict[str, Any] = {"target": f"stm32g4:{elf}", "link": "virtual", "controller": "external",
                               "speed": BOARD_SPEED_RPM, "load": BOARD_LOAD_NM}
    if board_file is not None:
        options["board"] = board_file
    try:
        cfg = _base(duration, ts, str(DEFAULTS["loop"]), **options)
    except HilError as exc:
        out["lockstep_stm32g4_error"] = str(exc)
        return out
    rates: list[float] = []
    for _ in range(max(repeats, 1)):
        try:
            res = run_closed_loop(cfg)
        except HilError as exc:
            out["lockstep_stm32g4_error"] = str(exc)
            return out
        ending = res.outcome
        if ending.end_code != EndCode.COMPLETED:
            out["lockstep_stm32g4_error"] = (f"the closed-loop run ended with exit {int(ending.end_code)} "
                                             f"({ending.end_reason}) after {ending.completed_periods} periods: no "
                                             "figure")
            return out
        rates.append(ending.completed_periods / ending.wall_time_s)
        out["stm32g4_cpu_load"] = res.metrics.get("board_cpu_load")
    out["lockstep_stm32g4_hz"] = statistics.median(rates)
    return out


def _board_only_rate(elf: Path, ts: float, duration: float, board_file: str | None = None) -> tuple[float, float]:
    """Periods per wall-clock second and per CPU second of this process (what the board costs, whatever else
    the machine runs) of the virtual board alone: its link fed `duration / ts` Measurements (a rotating field of
    10 A at 50 Hz electrical), the start-up not counted."""
    from pmsm_hil.protocol.codec import FrameCodec
    from pmsm_hil.protocol.messages import Measurement
    from pmsm_hil.sim_target.stm32g4.board_file import load_board
    from pmsm_hil.sim_target.stm32g4.link import BoardLink

    link = BoardLink(elf, load_board(board_file), ts_s=ts, pole_pairs=4)
    codec = FrameCodec("canfd")
    periods = max(round(duration / ts), 1)
    frames = []
    for k in range(periods):
        th = (2 * math.pi * 50.0 * k * ts) % (2 * math.pi)
        m = Measurement(seq=k & 0xFFFF, i_a=10 * math.cos(th), i_b=10 * math.cos(th - 2.094),
                        i_c=10 * math.cos(th + 2.094), theta_e=th, omega_m=78.5, vdc=48.0)
        frames.append(codec.encode(m))
    t0, c0 = time.perf_counter(), time.process_time()
    for f in frames:
        link.send(f)
        while link.poll() is not None:
            pass
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    return periods / wall, periods / max(cpu, 1e-9)


def run(args: argparse.Namespace) -> int:
    """Execute `hil bench loop`."""
    cross = [c.strip() for c in args.cross_process.split(",") if c.strip()]
    status = getattr(args, "status_line", None)

    def progress(msg: str) -> None:
        if status is not None and status.enabled:
            status.phase(msg)
        else:
            print(f"bench loop: {msg} ...", file=sys.stderr, flush=True)

    ts = float(coerce(OPTIONS["ts"], DEFAULTS["ts"] if args.ts is None else args.ts))
    board = None
    if args.board is not None:
        kind, elf = args.board
        if kind != "stm32g4":
            print(f"hil bench loop: error: --board {kind}: the virtual boards are: stm32g4", file=sys.stderr)
            return 2
        board = Path(elf)
    figures = measure(args.duration, args.repeats, cross, not args.no_realtime, progress, qemu=args.qemu,
                      load_fmu=args.load_fmu, ts=ts, board=board, board_file=args.board_file)
    load1, load5, _ = os.getloadavg()
    rate = 1.0 / ts
    print(f"closed loop, niu2020 IPMSM, MPCC, Ts = {ts * 1e6:g} µs, {args.duration} s simulated, median of "
          f"{args.repeats}; load average {load1:.2f} / {load5:.2f} (1 / 5 min) at the end")
    for key, value in figures.items():
        if key.startswith("udp_floor_") and key.endswith("_us"):
            print(f"  {key:<40} {value:>10.1f} µs per round trip (bare C, two processes)")
        elif key.endswith("_hz"):
            print(f"  {key:<40} {value:>10.0f} periods/s  ({value / rate:.2f}× real time at {rate / 1e3:g} kHz)")
        elif key.endswith("_load_ratio"):
            print(f"  {key:<40} {value:>10.2f} ×  (beside a CPU burner / idle, same run)")
        elif key in ("logging_cost_pct", "rerun_cost_pct", "load_fmu_cost_pct", "load_fmu_isolation_cost_pct"):
            print(f"  {key:<40} {value:>10.1f} %")
        elif key.startswith("native_speedup") or key in {f"{n}_native_speedup" for n in ADAPTER_PAIRS}:
            print(f"  {key:<40} {value:>10.2f} ×  (native / python, same run)")
        elif key == "logger_limit_stall_s":
            print(f"  {key:<40} {value:>10.3f} s  (the feeder waited for the logger's ring)")
        elif key not in ("duration_s", "repeats", "ts_s"):
            print(f"  {key:<40} {value}")
    if args.json is not None:
        write_text_atomic(args.json, json.dumps(figures, indent=2, default=str) + "\n", option="--json")
    return 0
