"""`hil run`: one closed-loop run of a scenario; prints a metrics table, optionally writes JSON."""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from pmsm_hil.app.cli.config_file import ConfigKey, load_config, schema_from_parser
from pmsm_hil.app.cli.motor_args import add_motor_arguments
from pmsm_hil.app.cli.parsing import finite_float, non_negative_int, positive_float
from pmsm_hil.app.cli.report_table import format_metrics
from pmsm_hil.dashboards.cli_live import add_rerun_arguments, live_dashboard
from pmsm_hil.hil.atomic_write import prepare_output_dir, refuse_inputs, write_text_atomic
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.motor_params import parse_set_options
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig, check_params_used, parse_param_options
from pmsm_hil.hil.runner.run_dir_lock import run_dir_lock
from pmsm_hil.hil.runner.run_limits import check_run_limits
from pmsm_hil.hil.runner.run_metadata import RUN_FILES
from pmsm_hil.hil.runner.scenario import load_scenario, scenario_names
from pmsm_hil.hil.sensors import SensorConfig
from pmsm_hil.protocol.ids import CONTROLLER_NAMES
from pmsm_hil.protocol.links.kinds import LINK_KINDS, PYTHON_CAN_ADAPTER
from pmsm_hil.protocol.links.spec import parse_spec
from pmsm_hil.sim_target.fw_params import default_controller  # issue 27 (helper cxx)

DEFAULTS: dict[str, Any] = {"motor": "niu2020-ipmsm", "controller": "mpcc", "scenario": "steady", "ts": 100e-6,
                            "link": "virtual", "mode": "lockstep", "target": "auto", "seed": 0,
                            "miss_policy": "hold", "watchdog_periods": 10, "adc_lsb": 0.0, "noise": 0.0,
                            "encoder_counts": 0, "no_log": False, "log_trace": False, "tolerate": 0,
                            "lockstep_timeout": 0.5, "overrun_threshold": None, "mcu_clock": 168e6,
                            "loop": "auto", "rt_priority": 0, "cpu": None, "step_timeout": 0.5,
                            "sil_in_process": False}

#: `hil run` exit codes (= metrics `end_code`), printed by --help.
EXIT_CODES = ("exit codes: 0 completed, 1 internal error, 2 usage/config error, 3 safety stop (watchdog, plant "
              "trip, target fault, safe stop not confirmed, SIL target crashed or hung), 4 DUT contract violation, "
              "130 interrupted (Ctrl-C/SIGTERM); every ending but 2 writes metrics.json (end_reason, end_period, "
              "end_code) and the log up to the last period")


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by `hil run` and `hil bench loop`."""
    p.add_argument("--config", type=Path, help="TOML file with any of the options below (CLI wins)")
    add_motor_arguments(p, default=None, shown_default=DEFAULTS["motor"])
    p.add_argument("--controller", metavar="NAME",
                   help=f"controller: {', '.join(CONTROLLER_NAMES.values())}{_default('controller')}")
    steady = load_scenario(DEFAULTS["scenario"])
    p.add_argument("--scenario", metavar="NAME|FILE.toml",
                   help=f"{' | '.join(scenario_names())} | FILE.toml{_default('scenario')}")
    p.add_argument("--speed", type=finite_float("--speed"), metavar="RPM",
                   help=f"speed reference [rpm] (default: the scenario's; {steady.name}: {steady.speed_rpm:g})")
    p.add_argument("--load", type=finite_float("--load"), metavar="NM",
                   help=f"load torque [N·m] (default: the scenario's; {steady.name}: {steady.load_nm:g})")
    p.add_argument("--duration", type=positive_float("--duration"), metavar="S",
                   help=f"metrics window [s], settling on top (default: the scenario's; {steady.name}: "
                        f"{steady.duration_s:g}); longer runs are refused when their buffers exceed half the "
                        "memory available (docs/runner.md)")
    p.add_argument("--settle", type=finite_float("--settle"), metavar="S",
                   help=f"settling time before the window [s] (default: the scenario's; {steady.name}: "
                        f"{steady.settle_s:g})")
    p.add_argument("--ts", type=positive_float("--ts"), metavar="S", help=f"control period [s]{_default('ts')}")
    p.add_argument("--link", metavar="SPEC",
                   help="link: " + "; ".join(k.summary for k in LINK_KINDS.values()) + "; "
                        + PYTHON_CAN_ADAPTER.summary + _default("link"))
    p.add_argument("--mode", choices=("lockstep", "realtime"),
                   help=f"virtual time or wall-clock pacing{_default('mode')}")
    p.add_argument("--target", metavar="KIND",
                   help="who runs the target: auto (virtual → in-process), inproc, spawn a `hil target` process, "
                        "external (a real board), sil:PATH (a firmware built with `hil fw build --board host`, or "
                        "its source folder, served from its own process) or qemu:PATH.elf (a firmware built for "
                        f"mps2-an386, run in QEMU over its emulated UART; docs/firmware_api.md){_default('target')}")
    p.add_argument("--mcu-clock", type=_clock_hz, metavar="HZ",
                   help="qemu targets: MCU clock of the execution-time estimate, Hz or with a unit (168MHz) "
                        "(default 168 MHz)")
    p.add_argument("--step-timeout", type=positive_float("--step-timeout"), metavar="S",
                   help="sil targets: wall time a firmware step may take before the target is 'hung' (exit 3) "
                        "[s]; the wait for each Command of a SIL run, in place of --lockstep-timeout"
                        f"{_default('step_timeout')}")
    p.add_argument("--sil-in-process", action="store_true", default=None,
                   help="sil targets: load the library into this process (UNPROTECTED: a crash of the firmware "
                        "ends `hil run` without metrics, an endless loop hangs it) instead of its own process")
    p.add_argument("--seed", type=non_negative_int("--seed"), help=f"seed for sensor noise{_default('seed')}")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="controller parameter (SI units), e.g. lambda=0.5, t_thr=8e-6, speed_kp=0.8")
    p.add_argument("--miss-policy", choices=("hold", "zero"),
                   help=f"real time: a late command → hold last/zero{_default('miss_policy')}")
    p.add_argument("--watchdog-periods", type=non_negative_int("--watchdog-periods"),
                   help="silent-target periods before the safe state (default 10)")
    p.add_argument("--tolerate", type=non_negative_int("--tolerate"),
                   help="DUT contract violations accepted before the run ends as one (default 0; counted in "
                        "dut_violations)")
    p.add_argument("--lockstep-timeout", type=positive_float("--lockstep-timeout"),
                   help="lockstep: wall time to wait for each Command before it is missing [s] (default 0.5)")
    p.add_argument("--fault", metavar="SPEC",
                   help="link fault injection on the host's link: drop=P,dup=P,corrupt=P,delay=D,jitter=D,"
                        "reorder=P,silence=T0:T1,seed=S (KEY.up / KEY.down per direction; docs/runner.md)")
    p.add_argument("--loop", choices=("auto", "native", "python"),
                   help="the period loop: the C loop (hil/native/loop.c) runs every run (auto = native); python is "
                        "the test suite's reference loop, not part of the product (an error outside the tests)"
                        f"{_default('loop')}")
    p.add_argument("--rt-priority", type=non_negative_int("--rt-priority"), metavar="N",
                   help="real time, native loop: SCHED_FIFO priority 1..99 of the loop thread (default 0: none; "
                        "refused without CAP_SYS_NICE, said in the warnings)")
    p.add_argument("--cpu", type=non_negative_int("--cpu"), metavar="N",
                   help="real time, native loop: pin the loop thread to this CPU (default: any)")
    p.add_argument("--overrun-threshold", type=positive_float("--overrun-threshold"),
                   help="real time: a period starting later than this is an overrun [s] (default Ts/2)")
    p.add_argument("--adc-lsb", type=finite_float("--adc-lsb"),
                   help="current quantisation step [A] (default 0: ideal)")
    p.add_argument("--noise", type=finite_float("--noise"),
                   help="current noise standard deviation [A] (default 0: none)")
    p.add_argument("--encoder-counts", type=non_negative_int("--encoder-counts"),
                   help="encoder counts/rev (default 0: ideal angle)")


def _clock_hz(text: str) -> float:
    """A clock frequency: Hz, or a number with kHz / MHz / GHz."""
    raw = text.strip().lower().replace(" ", "")
    scale = 1.0
    for unit, factor in (("ghz", 1e9), ("mhz", 1e6), ("khz", 1e3), ("hz", 1.0)):
        if raw.endswith(unit):
            raw, scale = raw[: -len(unit)], factor
            break
    try:
        value = float(raw) * scale
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--mcu-clock: expected a frequency (e.g. 168e6 or 168MHz), got {text!r}") from None
    if not (1e6 <= value <= 2e9):
        raise argparse.ArgumentTypeError(f"--mcu-clock must be between 1 MHz and 2 GHz, got {text!r}")
    return value


def _default(name: str) -> str:
    """" (default X)" for help texts, from DEFAULTS (the values a run really uses)."""
    return f" (default {DEFAULTS[name]:g})" if isinstance(DEFAULTS[name], float) else f" (default {DEFAULTS[name]})"


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `hil run`."""
    p = subparsers.add_parser("run", help="run a closed-loop scenario (default: the embedded demo)",
                              description="Closed-loop run. With no options: in-process virtual CAN, sim target, "
                                          "niu2020 IPMSM, MPCC, 1500 rpm, 7 N·m, lockstep.",
                              epilog=EXIT_CODES)
    _add_arguments(p)
    p.set_defaults(func=run)


def _add_arguments(p: argparse.ArgumentParser) -> None:
    """Every `hil run` option (the --config schema is derived from these)."""
    add_run_arguments(p)
    p.add_argument("--out", type=Path, help="output directory for run.mcap and metrics.json "
                                            "(default runs/<time>-<controller>); an existing run there is "
                                            "refused unless --overwrite")
    p.add_argument("--overwrite", action="store_true", default=None,
                   help="replace the run in --out (its run.mcap and metrics.json are removed first)")
    p.add_argument("--no-log", action="store_true", default=None, help="do not write an MCAP log")
    p.add_argument("--log-trace", action="store_true", default=None, help="also log the 2 µs plant trace")
    p.add_argument("--json", type=Path, help="write the metrics as JSON to this file")
    add_rerun_arguments(p)


@functools.cache
def config_schema() -> dict[str, ConfigKey]:
    """Keys a --config file may set: every `hil run` option but --config and the live-dashboard ones."""
    p = argparse.ArgumentParser(add_help=False)
    _add_arguments(p)
    rerun = {a.dest for a in p._actions if a.dest.startswith("rerun")}
    return schema_from_parser(p, exclude={"config", *rerun})


def _load_config(path: Path | None) -> dict[str, Any]:
    return {} if path is None else load_config(path, config_schema())


def config_from_args(args: argparse.Namespace) -> RunConfig:
    """Merge defaults < --config file < command line into a validated RunConfig."""
    cfg = _load_config(args.config)

    def pick(name: str, attr: str | None = None) -> Any:
        value = getattr(args, attr or name, None)
        if value is not None and value != []:
            return value
        return cfg.get(name, DEFAULTS.get(name))

    def source(name: str, fallback: str) -> str:
        """How an error names where a value came from: its option, its config key, else `fallback`."""
        spec = config_schema()[name]
        if getattr(args, spec.dest, None) is not None:
            return spec.option
        return f"'{name}' in config file {args.config}" if name in cfg else fallback

    for name in ("json", "overwrite"):  # used after the run: the config file's value unless given
        if getattr(args, name, None) is None and name in cfg:
            setattr(args, name, cfg[name])
    motor = load_motor(str(pick("motor")), parse_set_options([*cfg.get("set", []), *args.set_params]))
    scenario = load_scenario(str(pick("scenario"))).with_overrides(
        speed_rpm=pick("speed"), load_nm=pick("load"), duration_s=pick("duration"), settle_s=pick("settle"))
    controller_params = parse_param_options([*cfg.get("param", []), *args.param])
    out = pick("out")
    no_log = bool(pick("no_log"))
    controller = str(pick("controller"))
    # --- issue 27 (helper cxx): a user firmware (`--target sil:PATH` / `qemu:PATH`, not the reference firmware)
    # runs as controller `external` unless --controller (or the config file) names one
    if getattr(args, "controller", None) is None and "controller" not in cfg:
        controller = default_controller(str(pick("target")), controller)
    # --- end issue 27
    if out is None and not no_log:
        out = _fresh_dir(Path("runs") / f"{time.strftime('%Y%m%d-%H%M%S')}-{controller}")
    try:
        sensors = SensorConfig(adc_lsb_a=float(pick("adc_lsb")), noise_std_a=float(pick("noise")),
                               encoder_counts=int(pick("encoder_counts")), seed=int(pick("seed")))
        run_cfg = RunConfig(motor=motor, scenario=scenario, controller=controller, ts_s=float(pick("ts")),
                            link=str(pick("link")), mode=str(pick("mode")), target=str(pick("target")),
                            seed=int(pick("seed")), controller_params=controller_params, sensors=sensors,
                            out_dir=None if no_log else Path(out), log_trace=bool(pick("log_trace")),
                            miss_policy=str(pick("miss_policy")), watchdog_periods=int(pick("watchdog_periods")),
                            tolerate=int(pick("tolerate")), faults=str(pick("fault") or ""),
                            lockstep_timeout_s=float(pick("lockstep_timeout")),
                            step_timeout_s=float(pick("step_timeout")), sil_in_process=bool(pick("sil_in_process")),
                            mcu_clock_hz=float(pick("mcu_clock")), loop=str(pick("loop")),
                            rt_priority=int(pick("rt_priority")),
                            cpu=None if pick("cpu") is None else int(pick("cpu")),
                            overrun_threshold_s=None if pick("overrun_threshold") is None
                            else float(pick("overrun_threshold")))
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ParameterError):
            raise
        raise ParameterError(f"bad option value: {exc}") from None
    check_params_used(run_cfg.controller, run_cfg.controller_params)
    check_run_limits(run_cfg, speed_option=source("speed", f"scenario '{scenario.name}' speed_rpm"),
                     duration_option=source("duration", f"scenario '{scenario.name}' duration_s"))
    parse_spec(run_cfg.link)  # a bad --link fails here, before any output is created
    return run_cfg


def _check_outputs(args: argparse.Namespace, cfg: RunConfig, held: contextlib.ExitStack) -> None:
    """--json and --rerun-save never name an input or a file of the run directory; the run directory is
    created and locked for the run (`held`: a second run into it is refused), and an earlier run in it refused
    unless --overwrite (which removes it first)."""
    inputs = [Path(p) for p in (args.config, args.motor, args.scenario) if p is not None and Path(p).is_file()]
    if cfg.out_dir is not None:
        inputs += [cfg.out_dir / name for name in RUN_FILES]
    for option, path in (("--json", args.json), ("--rerun-save", getattr(args, "rerun_save", None))):
        if path is not None:
            refuse_inputs(path, inputs, option=option)
    if cfg.out_dir is not None:
        held.enter_context(run_dir_lock(cfg.out_dir, option="--out"))
        prepare_output_dir(cfg.out_dir, RUN_FILES, overwrite=bool(args.overwrite), option="--out")


def _fresh_dir(base: Path) -> Path:
    """`base`, or `base-2`, `base-3`, ... if a run of the same second already took it."""
    path, n = base, 2
    while path.exists():
        path, n = base.with_name(f"{base.name}-{n}"), n + 1
    return path


def run(args: argparse.Namespace) -> int:
    """Execute `hil run`."""
    cfg = config_from_args(args)
    with contextlib.ExitStack() as held:
        _check_outputs(args, cfg, held)
        return _run_checked(args, cfg)


def _run_checked(args: argparse.Namespace, cfg: RunConfig) -> int:
    try:
        with live_dashboard(args, cfg) as live:
            return _run_and_report(args, cfg, live)
    except KeyboardInterrupt:  # before the target was connected (from then on the run ends itself on Ctrl-C)
        if cfg.out_dir is None or not (cfg.out_dir / "run.mcap").exists():
            raise
        print(f"hil: interrupted; partial log: {cfg.out_dir / 'run.mcap'} (before the run started: no period, no "
              f"metrics.json)", file=sys.stderr)
        return 130


def _run_and_report(args: argparse.Namespace, cfg: RunConfig, live: Callable[[np.ndarray], None] | None) -> int:
    """One run (blocks also to the live dashboard if any); prints the metrics, writes --json."""
    result = run_closed_loop(cfg, live=live)
    print(format_metrics(result.metrics))
    for line in result.metrics.get("warnings", []):
        print(f"hil: warning: {line}", file=sys.stderr)
    end_code = int(result.metrics["end_code"])
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
