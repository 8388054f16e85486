"""`hil run`: one closed-loop run of a scenario; prints a metrics table, optionally writes JSON."""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import tomllib
from pmsm_hil.dashboards.cli_live import add_rerun_arguments, live_dashboard
from pmsm_hil.hil.cli.motor_args import add_motor_arguments
from pmsm_hil.hil.cli.parsing import finite_float, non_negative_int, positive_float
from pmsm_hil.hil.cli.report_table import format_metrics
from pmsm_hil.hil.errors import InputFileError, ParameterError
from pmsm_hil.hil.motor_params import parse_set_options
from pmsm_hil.hil.presets_loader import load_motor
from pmsm_hil.hil.runner.run import run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig, parse_param_options
from pmsm_hil.hil.runner.scenario import load_scenario
from pmsm_hil.hil.sensors import SensorConfig

#: Keys a --config TOML file may set (same names as the options, with underscores).
CONFIG_KEYS = {"motor", "controller", "scenario", "speed", "load", "duration", "settle", "ts", "link", "mode",
               "target", "out", "json", "seed", "set", "param", "no_log", "log_trace", "miss_policy",
               "watchdog_periods", "adc_lsb", "noise", "encoder_counts"}
DEFAULTS: dict[str, Any] = {"motor": "niu2020-ipmsm", "controller": "mpcc", "scenario": "steady", "ts": 100e-6,
                            "link": "virtual", "mode": "lockstep", "target": "auto", "seed": 0,
                            "miss_policy": "hold", "watchdog_periods": 10, "adc_lsb": 0.0, "noise": 0.0,
                            "encoder_counts": 0, "no_log": False, "log_trace": False}


def add_run_arguments(p: argparse.ArgumentParser) -> None:
    """Options shared by `hil run` and `hil bench loop`."""
    p.add_argument("--config", type=Path, help="TOML file with any of the options below (CLI wins)")
    add_motor_arguments(p, default=None)
    p.add_argument("--controller", help="controller name (default mpcc)")
    p.add_argument("--scenario", help="steady | speed-step | load-step | load-steps | accel | dyno-steady | "
                                      "FILE.toml (default steady)")
    p.add_argument("--speed", type=finite_float("--speed"), help="speed reference [rpm]")
    p.add_argument("--load", type=finite_float("--load"), help="load torque [N·m]")
    p.add_argument("--duration", type=positive_float("--duration"), help="metrics window [s] (settling on top)")
    p.add_argument("--settle", type=finite_float("--settle"), help="settling time before the window [s]")
    p.add_argument("--ts", type=positive_float("--ts"), help="control period [s] (default 100e-6)")
    p.add_argument("--link", help="link SPEC (default virtual: in-process python-can virtual bus)")
    p.add_argument("--mode", choices=("lockstep", "realtime"), help="virtual time or wall-clock pacing")
    p.add_argument("--target", choices=("auto", "inproc", "spawn", "external"),
                   help="who runs the target: auto (virtual → in-process), spawn a `hil target` process, "
                        "or external (a real board)")
    p.add_argument("--seed", type=non_negative_int("--seed"), help="seed for sensor noise")
    p.add_argument("--param", action="append", default=[], metavar="NAME=VALUE",
                   help="controller parameter (SI units), e.g. lambda=0.5, t_thr=8e-6, speed_kp=0.8")
    p.add_argument("--miss-policy", choices=("hold", "zero"), help="real time: a late command → hold last/zero")
    p.add_argument("--watchdog-periods", type=non_negative_int("--watchdog-periods"),
                   help="silent-target periods before the safe state (default 10)")
    p.add_argument("--adc-lsb", type=finite_float("--adc-lsb"), help="current quantisation step [A]")
    p.add_argument("--noise", type=finite_float("--noise"), help="current noise standard deviation [A]")
    p.add_argument("--encoder-counts", type=non_negative_int("--encoder-counts"), help="encoder counts/rev")


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `hil run`."""
    p = subparsers.add_parser("run", help="run a closed-loop scenario (default: the embedded demo)",
                              description="Closed-loop run. With no options: in-process virtual CAN, sim target, "
                                          "niu2020 IPMSM, MPCC, 1500 rpm, 7 N·m, lockstep.")
    add_run_arguments(p)
    p.add_argument("--out", type=Path, help="output directory for run.mcap and metrics.json "
                                            "(default runs/<time>-<controller>)")
    p.add_argument("--no-log", action="store_true", default=None, help="do not write an MCAP log")
    p.add_argument("--log-trace", action="store_true", default=None, help="also log the 2 µs plant trace")
    p.add_argument("--json", type=Path, help="write the metrics as JSON to this file")
    add_rerun_arguments(p)
    p.set_defaults(func=run)


def _load_config(path: Path | None) -> dict[str, Any]:
    if path is None:
        return {}
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputFileError(f"config file {path}: {exc.strerror}") from None
    except tomllib.TOMLDecodeError as exc:
        raise InputFileError(f"config file {path}: {exc}") from None
    unknown = set(doc) - CONFIG_KEYS
    if unknown:
        raise InputFileError(f"config file {path}: unknown key(s) {', '.join(sorted(unknown))} "
                             f"(known: {', '.join(sorted(CONFIG_KEYS))})")
    for key in ("set", "param"):
        if key in doc:
            if not isinstance(doc[key], dict):
                raise InputFileError(f"config file {path}: '{key}' must be a table of NAME = VALUE")
            doc[key] = [f"{k}={v}" for k, v in doc[key].items()]
    return doc


def config_from_args(args: argparse.Namespace) -> RunConfig:
    """Merge defaults < --config file < command line into a validated RunConfig."""
    cfg = _load_config(args.config)

    def pick(name: str, attr: str | None = None) -> Any:
        value = getattr(args, attr or name, None)
        if value is not None and value != []:
            return value
        return cfg.get(name, DEFAULTS.get(name))

    motor = load_motor(str(pick("motor")), parse_set_options([*cfg.get("set", []), *args.set_params]))
    scenario = load_scenario(str(pick("scenario"))).with_overrides(
        speed_rpm=pick("speed"), load_nm=pick("load"), duration_s=pick("duration"), settle_s=pick("settle"))
    controller_params = parse_param_options([*cfg.get("param", []), *args.param])
    out = pick("out")
    no_log = bool(pick("no_log"))
    controller = str(pick("controller"))
    if out is None and not no_log:
        out = Path("runs") / f"{time.strftime('%Y%m%d-%H%M%S')}-{controller}"
    try:
        sensors = SensorConfig(adc_lsb_a=float(pick("adc_lsb")), noise_std_a=float(pick("noise")),
                               encoder_counts=int(pick("encoder_counts")), seed=int(pick("seed")))
        return RunConfig(motor=motor, scenario=scenario, controller=controller, ts_s=float(pick("ts")),
                         link=str(pick("link")), mode=str(pick("mode")), target=str(pick("target")),
                         seed=int(pick("seed")), controller_params=controller_params, sensors=sensors,
                         out_dir=None if no_log else Path(out), log_trace=bool(pick("log_trace")),
                         miss_policy=str(pick("miss_policy")), watchdog_periods=int(pick("watchdog_periods")))
    except (TypeError, ValueError) as exc:
        if isinstance(exc, ParameterError):
            raise
        raise ParameterError(f"bad option value: {exc}") from None


def run(args: argparse.Namespace) -> int:
    """Execute `hil run`."""
    cfg = config_from_args(args)
    with live_dashboard(args, cfg) as live:
        return _run_and_report(args, cfg, live)


def _run_and_report(args: argparse.Namespace, cfg: RunConfig, live: Callable[[np.ndarray], None] | None) -> int:
    """One run (blocks also to the live dashboard if any); prints the metrics, writes --json."""
    result = run_closed_loop(cfg, live=live)
    print(format_metrics(result.metrics))
    if result.mcap_path is not None:
        print(f"log: {result.mcap_path}")
    if args.json is not None:
        try:
            args.json.write_text(json.dumps(result.metrics, indent=2) + "\n", encoding="utf-8")
        except OSError as exc:
            raise InputFileError(f"--json {args.json}: {exc.strerror}") from None
    return 0 if not result.outcome.safe_state else 3
