"""Entry point of the `hil` command: builds the parser from one module per subcommand."""

from __future__ import annotations

import argparse
import contextlib
import importlib
import os
import signal
import sys
from collections.abc import Callable
from types import FrameType, ModuleType
from typing import Any

# Nothing `hil` runs calls BLAS, but OpenBLAS starts a worker thread per extra core that spins ~0.05-0.1 s of
# CPU after numpy is imported (in this process and in the logger process, which inherits the environment):
# one thread unless the user chose otherwise. Set before the first numpy import (the subcommands, imported by
# `build_parser`).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

from pmsm_hil.errors import HilError

# (group or None, module): each module exposes add_parser(subparsers) that sets func=run.
_TOP_LEVEL = ("run", "target", "link_budget", "mcap_repair", "compare", "sweep", "replay_mcap", "report")
_GROUPS = {
    "plant": ("plant_replay", "plant_fluxmap"),
    "bench": ("bench_plant", "bench_loop", "bench_realtime", "bench_controllers", "bench_link", "bench_sweep",
              "bench_memory"),
    "fw": ("fw_build",),
    "mcap": ("mcap_export",),
    "fmu": ("fmu_example", "fmu_build"),
}
_GROUP_HELP = {"plant": "offline plant tools", "bench": "benchmarks that print figures",
               "fw": "build firmware for the SIL and QEMU targets", "mcap": "run log (MCAP) tools",
               "fmu": "load FMUs for --load-fmu: an example to start from, and its build"}


def _load(name: str) -> ModuleType | None:
    full = f"pmsm_hil.app.cli.{name}"
    try:
        return importlib.import_module(full)
    except ModuleNotFoundError as exc:
        if exc.name == full:
            return None  # subcommand not shipped in this build
        raise


def build_parser() -> argparse.ArgumentParser:
    """The complete `hil` argument parser."""
    parser, sub = _top_parser()
    for name in _TOP_LEVEL:
        module = _load(name)
        if module is not None:
            module.add_parser(sub)
    for group, names in _GROUPS.items():
        _add_group(sub, group, names)
    _add_debug(sub)
    return parser


def _add_group(sub: argparse._SubParsersAction[argparse.ArgumentParser], group: str, names: tuple[str, ...]) -> dict[
        str, argparse.ArgumentParser]:
    """The group's parser (`hil bench`, ...) with the subcommands of the modules `names`; returns its choices."""
    group_parser = sub.add_parser(group, help=_GROUP_HELP[group])
    group_sub = group_parser.add_subparsers(dest=f"{group}_command", metavar="COMMAND")
    for name in names:
        module = _load(name)
        if module is not None:
            module.add_parser(group_sub)
    if group == "bench":
        for name, p in group_sub.choices.items():
            _with_status_line(p, f"hil bench {name}")
    group_parser.set_defaults(func=lambda args, p=group_parser: _usage(p))
    return group_sub.choices


def _with_status_line(p: argparse.ArgumentParser, label: str) -> None:
    """A live status line around the subcommand (its phase, the time it takes; app/cli/status_line.py) and its
    `--quiet`; the subcommand may tell its stages through `args.status_line.phase`."""
    if not any("--quiet" in a.option_strings for a in p._actions):
        p.add_argument("--quiet", action="store_true", help="no live status line (drawn only on a terminal)")
    func = p.get_default("func")

    def with_status(args: argparse.Namespace) -> int:
        from pmsm_hil.app.cli.status_line import StatusLine, status_wanted

        with StatusLine(label, enabled=status_wanted(args.quiet)) as line:
            line.phase("measuring")
            args.status_line = line
            code = int(func(args))
            line.close("done")
        return code

    p.set_defaults(func=with_status)


def _top_parser() -> tuple[argparse.ArgumentParser, argparse._SubParsersAction[argparse.ArgumentParser]]:
    parser = argparse.ArgumentParser(prog="hil", description="PMSM drive hardware-in-the-loop tester")
    parser.add_argument("--debug", action="store_true", help="show tracebacks on errors")
    return parser, parser.add_subparsers(dest="command", metavar="COMMAND")


def parser_for(argv: list[str]) -> argparse.ArgumentParser:
    """The parser `main` parses `argv` with: when `argv` names a top-level subcommand whose module has its name
    ("run", "target", ...; nothing but --debug before it), or a group's subcommand whose module is named after
    both ("fw build": fw_build, "bench loop": bench_loop), one that knows only that subcommand and imports only its
    module (a spawned `hil target` imports no runner: ~0.5 CPU-s of each start-up; `hil fw build` none of the
    other ~25 subcommands: ~0.5 CPU-s); else `build_parser()` (`hil --help`, a group alone, a mistyped command)."""
    words = [a for a in argv if a != "--debug"]
    command = words[0] if words else None
    if command in _GROUPS and len(words) > 1:
        return _group_parser_for(command, words[1]) or build_parser()
    module = _load(command) if command is not None and command in _TOP_LEVEL else None
    if module is None:
        return build_parser()
    parser, sub = _top_parser()
    module.add_parser(sub)
    if command not in sub.choices:
        return build_parser()
    _add_debug(sub)
    return parser


def _group_parser_for(group: str, command: str) -> argparse.ArgumentParser | None:
    """A parser that knows only `hil GROUP COMMAND`, when the group's module `GROUP_COMMAND` defines it."""
    name = f"{group}_{command.replace('-', '_')}"
    if name not in _GROUPS[group]:
        return None
    parser, sub = _top_parser()
    if command not in _add_group(sub, group, (name,)):
        return None
    _add_debug(sub)
    return parser


def _add_debug(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """`--debug` after any (sub)command too (`hil run --debug`); absent there, the top-level value stands."""
    for p in set(sub.choices.values()):
        p.add_argument("--debug", action="store_true", default=argparse.SUPPRESS, help="show tracebacks on errors")
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                _add_debug(action)


def _usage(parser: argparse.ArgumentParser) -> int:
    parser.print_help()
    return 2


def main(argv: list[str] | None = None) -> int:
    """Run the `hil` command line; returns the process exit code (130 on Ctrl-C or SIGTERM, no traceback).

    SIGTERM is Ctrl-C for every subcommand (a KeyboardInterrupt, deferred by `hil run` while its loop and
    outputs are written). Called as the `hil` command (`argv` None), both signals are ignored once the
    subcommand returned: its exit code and files stand."""
    cli = argv is None
    argv = sys.argv[1:] if argv is None else argv
    _interrupted.clear()
    previous = _interrupts_raise()
    try:
        code = _main(argv)
    except BaseException as exc:
        if not (isinstance(exc, KeyboardInterrupt) or _interrupted):
            raise
        # an import cut by the signal can surface as another error (numpy: ImportError): still an interrupt
        if cli:
            _ignore_interrupts()
        print("hil: interrupted", file=sys.stderr)
        code = 130
    finally:
        if cli:
            _ignore_interrupts()
            if _interrupted:
                _forget_unhandled_interrupt()
        else:
            for signum, handler in previous.items():
                signal.signal(signum, handler)
    if cli and code == 130 and next((a for a in argv if not a.startswith("-")), "run") == "run":
        _exit_at_once(code)  # `hil run` (also `hil` alone): its outputs are written, the user wants it gone
    return code


#: commands with a live status line (app/cli/status_line.py): drawn before the imports, from the first words
_STATUS_COMMANDS = {("run",): 1, ("replay",): 1, ("bench",): 2, ("fw", "build"): 2}


def _early_status(argv: list[str]) -> Callable[[], None]:
    """`hil run: starting…` on a terminal at once for a command with a status line (its imports take seconds
    on a loaded machine); returns what erases it."""
    if any(a in ("-h", "--help", "--quiet", "--verbose") for a in argv):
        return lambda: None
    words = [a for a in argv if not a.startswith("-")]
    for head, n in _STATUS_COMMANDS.items():
        if tuple(words[:len(head)]) == head and len(words) >= n:
            from pmsm_hil.app.cli.status_line import early_status

            return early_status(" ".join(["hil", *words[:n]]))
    return lambda: None


def _main(argv: list[str]) -> int:
    if not argv or (argv[0] == "--debug" and len(argv) == 1):
        argv = [*argv, "run"]  # `hil` alone runs the embedded default
    erase = _early_status(argv)
    try:  # imports the subcommand(s): the protocol's layouts are compiled from hil.dbc here
        parser = parser_for(argv)
    except HilError as exc:  # a malformed hil.dbc (DatabaseError naming the line and field): one line too
        erase()
        if "--debug" in argv:
            raise
        print(f"hil: error: {exc}", file=sys.stderr)
        return 2
    finally:  # Ctrl-C in the imports too: `hil: interrupted` on a clean line
        erase()  # the command's own status line takes over (argparse's usage errors come on a clean line)
    args = parser.parse_args(argv)
    func = getattr(args, "func", None)
    if func is None:
        parser.print_help()
        return 2
    try:
        return int(func(args))
    except HilError as exc:  # the package's one root (pmsm_hil.errors): bad input or a failed run, one line
        if args.debug:
            raise
        print(f"hil: error: {exc}", file=sys.stderr)
        return 2


#: signals that raised KeyboardInterrupt in this process (through `_raise_interrupt`)
_interrupted: list[int] = []


def _raise_interrupt(signum: int, frame: FrameType | None) -> None:
    _interrupted.append(signum)
    raise KeyboardInterrupt


def _interrupts_raise() -> dict[int, Any]:
    """Ctrl-C raises KeyboardInterrupt as by default, and SIGTERM the same where it would kill, both through
    `_raise_interrupt` (which records them); returns the handlers replaced (none off the main thread, or for a
    signal ignored or handled by the caller)."""
    replaced: dict[int, Any] = {}
    for signum, default in ((signal.SIGINT, signal.default_int_handler), (signal.SIGTERM, signal.SIG_DFL)):
        try:
            if signal.getsignal(signum) == default:
                replaced[signum] = signal.signal(signum, _raise_interrupt)
        except ValueError:  # not the main thread
            break
    return replaced


def _forget_unhandled_interrupt() -> None:
    """CPython 3.11 marks a KeyboardInterrupt that left code run by exec() or eval() of a string (dataclasses
    and namedtuple build their methods so, on import) as unhandled even when it is caught later, and then ends
    the process by SIGINT instead of with its exit code (a subprocess caller sees -2, not 130). `hil` handled
    it: clear the mark (a private flag; nothing is done where it does not exist)."""
    try:
        import ctypes

        ctypes.c_int.in_dll(ctypes.pythonapi, "_Py_UnhandledKeyboardInterrupt").value = 0
    except (ImportError, ValueError, OSError, AttributeError):
        pass


def _exit_at_once(code: int) -> None:
    """End the `hil` process now, an interrupted run's outputs written and closed: stdio flushed, the
    interpreter's teardown skipped (module and object finalisation took 1–1.5 s of wall time on a loaded 2-core
    machine, against Ctrl-C/SIGTERM's 1 s)."""
    with contextlib.suppress(Exception):
        sys.stdout.flush()
    with contextlib.suppress(Exception):
        sys.stderr.flush()
    os._exit(code)


def _ignore_interrupts() -> None:
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(ValueError):
            signal.signal(sig, signal.SIG_IGN)


if __name__ == "__main__":
    sys.exit(main())
