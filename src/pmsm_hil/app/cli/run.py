"""`hil run`: one closed-loop run of a scenario; prints a metrics table, optionally writes JSON."""

from __future__ import annotations

import argparse
import contextlib
import functools
import importlib
import json
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pmsm_hil.app.cli.config_file import ConfigKey, load_config
from pmsm_hil.app.cli.run_options_cli import add_options, config_keys
from pmsm_hil.app.cli.status_line import StatusLine, status_wanted
from pmsm_hil.dashboards.cli_live import add_rerun_arguments
from pmsm_hil.hil.atomic_write import prepare_output_dir, refuse_inputs, write_text_atomic
from pmsm_hil.hil.runner.option_values import layer, option_of
from pmsm_hil.hil.runner.run_dir_lock import run_dir_lock
from pmsm_hil.hil.runner.run_options import RUN_OPTIONS, Scope

if TYPE_CHECKING:
    import numpy as np

    from pmsm_hil.app.cli.run_status import RunStatus
    from pmsm_hil.hil.runner.run_config import RunConfig

#: what only a run needs (the runner, numpy, the metrics table, the live dashboard), imported when `run` runs:
#: `hil run --help`, a usage error and `hil sweep`'s parser import none of it. Kept as names of this module
#: (`_lazy`, `__getattr__`), where a test may replace one.
_LAZY = {
    "run_closed_loop": "pmsm_hil.hil.runner.run",
    "RunConfig": "pmsm_hil.hil.runner.run_config",
    "RUN_FILES": "pmsm_hil.hil.runner.run_metadata",
    "RunStatus": "pmsm_hil.app.cli.run_status",
    "format_metrics": "pmsm_hil.app.cli.report_table",
    "live_dashboard": "pmsm_hil.dashboards.cli_live",
}


def _lazy(name: str) -> Any:
    """The `_LAZY` name `name`, imported on first use and kept in this module's namespace."""
    if name not in globals():
        globals()[name] = getattr(importlib.import_module(_LAZY[name]), name)
    return globals()[name]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return _lazy(name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


#: `hil run` exit codes (= metrics `end_code`), printed by --help.
EXIT_CODES = ("exit codes: 0 completed, 1 internal error, 2 usage/config error, 3 safety stop (watchdog, plant "
              "trip, target fault, safe stop not confirmed, SIL target crashed or hung, a shared bus flooded by other "
              "nodes: end_reason \"bus ...\"), 4 DUT contract violation, "
              "5 setpoint not held (--expect-hold: a completed run with setpoint_held false), 130 interrupted "
              "(Ctrl-C/SIGTERM); every ending but 2 writes metrics.json (end_reason, end_period, end_code) and the log "
              "up to the last period")


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by `hil run` and `hil sweep` (its base options): --config, then the run-option schema's
    (src/pmsm_hil/hil/runner/run_options.py)."""
    p.add_argument("--config", type=Path, help="TOML file with any of the options below (CLI wins)")
    add_options(p, ("run",))


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `hil run`."""
    p = subparsers.add_parser("run", help="run a closed-loop scenario (default: the embedded demo)",
                              description="Closed-loop run. With no options: in-process virtual CAN, sim target, "
                                          "niu2020 IPMSM, MPCC, 1500 rpm, 7 N·m, lockstep.",
                              epilog=EXIT_CODES)
    _add_arguments(p)
    bench = p.add_argument_group("bench (labgrid; the `bench` extra)")
    bench.add_argument("--place", metavar="NAME",
                       help="run on the labgrid place NAME: wait for it, acquire it, flash its board, wait for its "
                            "heartbeat, run over its link (--target external), release it (docs/bench_setup.md)")
    bench.add_argument("--coordinator", metavar="HOST:PORT",
                       help="labgrid coordinator of --place (default: LG_COORDINATOR, else 127.0.0.1:20408)")
    p.set_defaults(func=run)


def _add_arguments(p: argparse.ArgumentParser) -> None:
    """Every `hil run` option: the run options, its outputs, the live dashboard's."""
    add_run_arguments(p)
    add_options(p, ("output",))
    p.add_argument("--quiet", action="store_true",
                   help="no live status line (drawn on stderr only when stdout and stderr are terminals)")
    add_rerun_arguments(p)


@functools.cache
def config_schema() -> dict[str, ConfigKey]:
    """Keys a --config file may set: every option of the run-option schema (src/pmsm_hil/hil/runner/run_options.py)."""
    return config_keys()


def _load_config(path: Path | None) -> dict[str, Any]:
    return {} if path is None else load_config(path, config_schema())


def options_from_args(args: argparse.Namespace, scopes: tuple[Scope, ...] = ("run", "output")
                      ) -> tuple[dict[str, Any], dict[str, str]]:
    """The run-option values of a parsed command line over its --config file, with their sources ("config file
    PATH", "--option"): defaults < --config file < command line (src/pmsm_hil/hil/runner/run_inputs.py). Options of
    `scopes` only (`hil sweep` has an --out of its own)."""
    path = getattr(args, "config", None)
    cfg = _load_config(path)
    given = {o.key: getattr(args, o.target) for o in RUN_OPTIONS if o.scope in scopes and hasattr(args, o.target)}
    return layer((cfg, f"config file {path}"), ({k: v for k, v in given.items() if v != []}, _option_source))


def _option_source(key: str) -> str:
    return option_of(key).option


def config_from_args(args: argparse.Namespace) -> RunConfig:
    """Merge defaults < --config file < command line into a validated RunConfig (`RunConfig.from_options`); the
    outputs used after the run (--json, --overwrite, --expect-hold) are taken from the config file unless given."""
    values, sources = options_from_args(args)
    run_config: type[RunConfig] = _lazy("RunConfig")
    for name in ("json", "overwrite", "expect_hold"):
        if getattr(args, name, None) is None and name in values:
            setattr(args, name, values[name])
    return run_config.from_options(values, sources)


def _check_outputs(args: argparse.Namespace, cfg: RunConfig, held: contextlib.ExitStack) -> None:
    """--json and --rerun-save never name an input or a file of the run directory; the run directory is
    created and locked for the run (`held`: a second run into it is refused), and an earlier run in it refused
    unless --overwrite (which removes it first)."""
    inputs = [Path(p) for p in (args.config, args.motor, args.scenario) if p is not None and Path(p).is_file()]
    if cfg.out_dir is not None:
        inputs += [cfg.out_dir / name for name in _lazy("RUN_FILES")]
    for option, path in (("--json", args.json), ("--rerun-save", getattr(args, "rerun_save", None))):
        if path is not None:
            refuse_inputs(path, inputs, option=option)
    if cfg.out_dir is not None:
        held.enter_context(run_dir_lock(cfg.out_dir, option="--out"))
        prepare_output_dir(cfg.out_dir, _lazy("RUN_FILES"), overwrite=bool(args.overwrite), option="--out")


def run(args: argparse.Namespace) -> int:
    """Execute `hil run` (with --place: on that labgrid place, `run_on_place`)."""
    if getattr(args, "place", None) is not None:
        return run_on_place(args)
    return _run_here(args)


def run_on_place(args: argparse.Namespace) -> int:
    """`hil run --place NAME`: lease the place (waiting for it), bring its board to ready, run over its link and
    release it, whatever the ending; a board that gives no heartbeat, or stops answering during the run (a safety
    stop), ends the run with exit 3 naming the bench."""
    from pmsm_hil.bench.errors import BoardSilentError
    from pmsm_hil.bench.heartbeat import wait_heartbeat
    from pmsm_hil.bench.session import open_bench

    place = str(args.place)
    silent = None
    try:
        with open_bench(place, coordinator=args.coordinator) as bench:
            args.link, args.target = bench.link, "external"
            code = _run_here(args)
            if code in (3, 4) and wait_heartbeat(bench.link, BOARD_CHECK_S) is None:
                silent = (f"bench {place}: the board stopped answering (no heartbeat on {bench.link} within "
                          f"{BOARD_CHECK_S:g} s after the run)")
    except BoardSilentError as exc:
        print(f"hil: {exc}; place {place} released", file=sys.stderr)
        return 3
    if silent is not None:
        _mark_safety_stop(args, silent)
        print(f"hil: {silent}; place {place} released", file=sys.stderr)
        return 3
    return code


#: how long `hil run --place` waits for the board's heartbeat after a run that ended with exit 3 or 4 [s]
BOARD_CHECK_S = 3.0


def _mark_safety_stop(args: argparse.Namespace, reason: str) -> None:
    """A board that stopped answering is a safety stop: metrics.json (and --json) say end_code 3 and the bench."""
    out = getattr(args, "out", None)
    for path in (None if out is None else Path(out) / "metrics.json", getattr(args, "json", None)):
        if path is not None and Path(path).is_file():
            metrics = json.loads(Path(path).read_text(encoding="utf-8"))
            metrics["end_code"] = 3
            metrics["end_reason"] = f"{reason}; {metrics.get('end_reason', '')}"
            write_text_atomic(Path(path), json.dumps(metrics, indent=2) + "\n", option="--place")


def _run_here(args: argparse.Namespace) -> int:
    with StatusLine("hil run", enabled=status_wanted(getattr(args, "quiet", False))) as line:
        line.phase("checking options…")
        cfg = config_from_args(args)
        with contextlib.ExitStack() as held:
            _check_outputs(args, cfg, held)
            return _run_checked(args, cfg, _lazy("RunStatus")(line, cfg))


def _run_checked(args: argparse.Namespace, cfg: RunConfig, status: RunStatus) -> int:
    try:
        with _lazy("live_dashboard")(args, cfg) as live:
            return _run_and_report(args, cfg, live, status)
    except KeyboardInterrupt:  # before the target was connected (from then on the run ends itself on Ctrl-C)
        if cfg.out_dir is None or not (cfg.out_dir / "run.mcap").exists():
            raise
        print(f"hil: interrupted; partial log: {cfg.out_dir / 'run.mcap'} (before the run started: no period, no "
              f"metrics.json)", file=sys.stderr)
        return 130


def _both(first: Callable[[np.ndarray], None], second: Callable[[np.ndarray], None]) -> Callable[[np.ndarray], None]:
    def both(periods: np.ndarray) -> None:
        first(periods)
        second(periods)
    return both


#: exit code (= metrics `end_code`) of a completed run whose setpoint was not held under `--expect-hold`
EXIT_SETPOINT_NOT_HELD = 5


def _setpoint_missed(metrics: dict[str, Any], cfg: RunConfig) -> int:
    """`--expect-hold` and the setpoint was not held: end_code 5 in the metrics (metrics.json rewritten)."""
    metrics["end_code"] = EXIT_SETPOINT_NOT_HELD
    err = metrics.get("setpoint_error") or {}
    metrics["end_reason"] = (f"setpoint not held (--expect-hold): speed {err.get('measured', float('nan')):.1f} rpm "
                             f"vs {err.get('reference', float('nan')):.1f} rpm, tolerance "
                             f"±{metrics.get('hold_tolerance_pct')} %")
    if cfg.out_dir is not None:
        write_text_atomic(cfg.out_dir / "metrics.json", json.dumps(metrics, indent=2) + "\n", option="metrics file")
    return EXIT_SETPOINT_NOT_HELD


def _run_and_report(args: argparse.Namespace, cfg: RunConfig, live: Callable[[np.ndarray], None] | None,
                    status: RunStatus) -> int:
    """One run (blocks also to the live dashboard if any, and to the status line); prints the metrics, writes
    --json."""
    blocks = status.block if live is None else _both(live, status.block)
    result = _lazy("run_closed_loop")(cfg, live=blocks if status.line.enabled else live, phase=status.phase,
                             counter=status.counter if status.line.enabled else None)
    status.line.close(f"ended (exit {result.metrics['end_code']})" if result.metrics["end_code"] else "completed")
    end_code = int(result.metrics["end_code"])
    if end_code == 0 and getattr(args, "expect_hold", False) and result.metrics.get("setpoint_held") is False:
        end_code = _setpoint_missed(result.metrics, cfg)
    print(_lazy("format_metrics")(result.metrics))
    for line in result.metrics.get("warnings", []):
        print(f"hil: warning: {line}", file=sys.stderr)
    if result.outcome.error is not None and args.debug:
        raise result.outcome.error
    if end_code != 0:
        where = f"; partial log: {result.mcap_path}" if result.mcap_path is not None else ""
        print(f"hil: run ended (exit {end_code}): {result.metrics['end_reason']}{where}", file=sys.stderr)
    if result.mcap_path is not None:
        print(f"log: {result.mcap_path}")
    if args.json is not None:
        write_text_atomic(args.json, json.dumps(result.metrics, indent=2) + "\n", option="--json")
    return end_code
