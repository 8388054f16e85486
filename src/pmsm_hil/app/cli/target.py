"""`hil target`: run the virtual target (firmware stub) in its own process on a link."""

from __future__ import annotations

import argparse
import json
import sys


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `hil target`."""
    p = subparsers.add_parser("target", help="run the virtual target on a link (its own process)",
                              description="""Serve the C reference firmware over a link until SIGTERM/Ctrl-C. The host
                                             selects the controller with its setpoint; --controller preselects one.
                                             Prints 'ready LINK' once the link is open; a link that cannot open (e.g. a
                                             UDP port in use) is a one-line error, exit 2.""")
    p.add_argument("--link", required=True, help="link SPEC, e.g. udp:LOCAL:REMOTE, serial:/dev/pts/3, socketcan:can0")
    p.add_argument("--controller", help="controller to preselect (e.g. mpcc)")
    p.add_argument("--role", default="target", choices=("target", "host"),
                   help="end of a point-to-point link this process takes (default target)")
    p.add_argument("--idle-timeout", type=_positive, default=None, metavar="S",
                   help="stop after S seconds without a frame (default: never; targets spawned by "
                        "`hil run` get 30)")
    p.add_argument("--parent-pid", type=int, default=None, metavar="PID",
                   help="stop when process PID (this process's parent) exits (set by `hil run --target spawn`)")
    p.add_argument("--native", action="store_true",
                   help="serve from a C loop (udp links only; what `hil run --target spawn` starts for the native "
                        "loop)")
    p.add_argument("--sil", metavar="PATH",
                   help="serve this SIL library (`hil fw build --board host`) from the C loop instead of the "
                        "reference firmware (implies --native; what `hil run --target sil:PATH` starts)")
    p.add_argument("--sil-debug-fd", type=int, default=None, help=argparse.SUPPRESS)  # set by `hil run` (sil:)
    p.add_argument("--auth-key-stdin", action="store_true",
                   help="read the frames' authentication key (hex) as a line from stdin: how `hil run` hands a "
                        "spawned target its key (docs/protocol.md, 'Authenticated frames')")
    p.add_argument("--rt-priority", type=int, default=0, metavar="N",
                   help="with --native: serve at SCHED_FIFO priority N (1-99; what `hil run --mode realtime "
                        "--rt-priority N --target spawn` starts); refused without CAP_SYS_NICE: a warning, served at "
                        "normal priority")
    p.add_argument("--spin-us", type=_spin_us, default=None, metavar="US",
                   help="with --native: busy-poll at most US µs for a frame before blocking (default: 50, 0 on one "
                        "CPU; 0: always block — what `hil run --mode realtime` starts on a machine with fewer than "
                        "three CPUs, where a spinning target takes the CPU the run's logging needs)")
    p.set_defaults(func=run)


def _fifo(priority: int) -> None:
    """This thread at SCHED_FIFO `priority` (the C serve loop runs in it); a refusal is a warning on stderr."""
    import os
    import sys

    from pmsm_hil.hil.errors import ParameterError

    if not 1 <= priority <= 99:
        raise ParameterError(f"--rt-priority must be 1..99, got {priority}")
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except OSError as exc:
        print(f"hil: warning: --rt-priority {priority}: SCHED_FIFO not permitted ({exc.strerror}); serving at "
              "normal priority", file=sys.stderr, flush=True)


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--idle-timeout must be a number of seconds, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"--idle-timeout must be positive and finite, got {text!r}")
    return value


def _spin_us(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"--spin-us must be a number of µs, got {text!r}") from None
    if not 0 <= value <= 1e6:
        raise argparse.ArgumentTypeError(f"--spin-us must be 0..1000000 µs, got {text!r}")
    return value


def _link_spec(args: argparse.Namespace) -> str:
    """--link, with the key read from stdin when --auth-key-stdin (LinkSpecError naming it when not a key)."""
    if not args.auth_key_stdin:
        return str(args.link)
    from pmsm_hil.protocol.links.auth import parse_key

    key = parse_key(sys.stdin.readline(), "--auth-key-stdin")
    head, *opts = str(args.link).split(",")
    return ",".join([head, *(o for o in opts if o.partition("=")[0].strip() != "key"), f"key={key.hex()}"])


def _ready(args: argparse.Namespace) -> None:
    from pmsm_hil.protocol.links.spec import redact_spec
    from pmsm_hil.sim_target.process import READY_LINE

    print(f"{READY_LINE} {redact_spec(args.link)}", flush=True)


def run(args: argparse.Namespace) -> int:
    """Execute `hil target`."""
    from pmsm_hil.sim_target.process import LINK_STATS_LINE, serve

    args.spec = _link_spec(args)
    if args.native or args.sil is not None:
        return _run_native(args)
    for given, option in ((args.rt_priority, "--rt-priority"), (args.spin_us is not None, "--spin-us")):
        if given:
            from pmsm_hil.hil.errors import ParameterError

            raise ParameterError(f"{option}: with --native only (the Python target is not a real-time loop)")

    served = serve(args.spec, args.controller, role=args.role, max_idle_s=args.idle_timeout,
                   parent_pid=args.parent_pid, on_ready=lambda: _ready(args))
    c = served.target.counters
    print(f"target stopped ({served.reason}): {c.measurements} measurements, {c.commands} commands, "
          f"{c.config_writes} config writes ({c.config_rejected} rejected), {c.faults} faults")
    print(f"{LINK_STATS_LINE} {json.dumps(served.link_stats)}", flush=True)
    return 0


def _run_native(args: argparse.Namespace) -> int:
    from pmsm_hil.hil.errors import ParameterError
    from pmsm_hil.hil.runner.target_serve import serve_native
    from pmsm_hil.sim_target.process import LINK_STATS_LINE

    if args.controller is not None:
        raise ParameterError("--controller: not with --native (the host's Setpoint selects the controller)")
    if args.rt_priority:
        _fifo(args.rt_priority)
    served = serve_native(args.spec, role=args.role, max_idle_s=args.idle_timeout, parent_pid=args.parent_pid,
                          on_ready=lambda: _ready(args), sil=args.sil, sil_debug_fd=args.sil_debug_fd,
                          spin_ns=None if args.spin_us is None else round(args.spin_us * 1e3))
    c = served.counters
    print(f"target stopped ({served.reason}): {c['measurements']} measurements, {c['commands']} commands, "
          f"{c['config_writes']} config writes ({c['config_rejected']} rejected), {c['faults']} faults "
          f"({'sil' if args.sil is not None else 'native'})")
    print(f"{LINK_STATS_LINE} {json.dumps(served.link_stats)}", flush=True)
    return 0
