"""`hil replay RUN.mcap --output OUT.csv`: the run's Commands through the plant as its loop applied them, the set-up
from the log, the replayed currents compared with the logged ones (`--run-log RUN.mcap` with a CAN log of the run:
the Commands from the capture); `hil replay CAPTURE.log --rpm N --ts S --output OUT.csv`: a CAN log (candump -L .log,
.asc, .blf, python-can .csv) alone through the plant at a held speed; `hil replay RUN.mcap --rerun…`: a recorded run
into the Rerun dashboard (viewer, .rrd file or web viewer)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from pmsm_hil.app.cli.motor_args import add_motor_arguments
from pmsm_hil.app.cli.parsing import finite_float, positive_float
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.pwm import PWM_UPDATES

if TYPE_CHECKING:
    import numpy as np

    from pmsm_hil.hil.machine_params import MachineParams

#: a replay within this of the logged phase currents [A] reproduces the run
REPRODUCED_A = 1e-6


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `hil replay`."""
    from pmsm_hil.dashboards.cli_live import add_rerun_arguments

    p = subparsers.add_parser("replay", help="replay a recorded run through the plant (--output) or into the Rerun "
                                             "dashboard",
                              description="""With --output: the run's Commands drive the plant as the run's loop applied
                                             them (the set-up from the run log's metadata) and the replayed currents
                                             are compared with the logged ones; the Commands of a CAN log of the run
                                             (.log candump -L, .asc, .blf, python-can .csv, e.g. from `hil mcap
                                             export`) with --run-log RUN.mcap, or of any CAN log at a held speed with
                                             --rpm and --ts. Without it: a run.mcap of `hil run` into the same blueprint
                                             as the live dashboard (--rerun, --rerun-save FILE.rrd and/or
                                             --rerun-serve).""")
    p.add_argument("mcap", type=Path, metavar="RUN.mcap|CAPTURE.log",
                   help="run log written by `hil run`, or a CAN log whose Commands to replay through the plant")
    p.add_argument("--vdc", type=positive_float("--vdc"), help="DC-link voltage [V] (default: the run's motor)")
    add_rerun_arguments(p)
    plant = p.add_argument_group(
        "through the plant (--output): the run's Commands drive the plant as its loop did (`hil replay RUN.mcap "
        "--output OUT.csv`: the set-up from the log; a CAN log with --run-log RUN.mcap, or with --rpm and --ts)")
    add_motor_arguments(plant, default=None, shown_default="the run's, else niu2020-ipmsm")  # type: ignore[arg-type]
    plant.add_argument("--output", type=Path, help="output CSV (t, currents, torque, angle, speed per period start)")
    plant.add_argument("--run-log", type=Path, metavar="RUN.mcap",
                       help="a CAN log's run: machine, Ts, mechanics and start state from its metadata, the replayed "
                            "currents compared with its logged ones")
    plant.add_argument("--allow-gaps", action="store_true",
                       help="replay a capture with missing Commands, each held as the zero vector (counted); without "
                            "it the first missing seq is an error")
    plant.add_argument("--rpm", type=finite_float("--rpm"), help="a CAN log without --run-log: held shaft speed [rpm]")
    plant.add_argument("--ts", type=positive_float("--ts"), help="a CAN log without --run-log: control period [s]")
    plant.add_argument("--theta0", type=finite_float("--theta0"),
                       help="a CAN log without --run-log: initial electrical angle [rad]")
    plant.add_argument("--pwm-update", choices=PWM_UPDATES,
                       help="a CAN log without --run-log: the carrier of duty-cycle Commands (default single)")
    p.add_argument("--quiet", action="store_true", help="no live status line (drawn only on a terminal)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute `hil replay` under its status line (app/cli/status_line.py)."""
    from pmsm_hil.app.cli.status_line import StatusLine, status_wanted

    with StatusLine("hil replay", enabled=status_wanted(args.quiet)) as status:
        status.phase(f"reading {args.mcap.name}")
        args.status_line = status
        code = _run(args)
        status.close("done")
    return code


def _run(args: argparse.Namespace) -> int:
    from pmsm_hil.dashboards.cli_live import hold_serving, rerun_targets
    from pmsm_hil.dashboards.errors import DashboardError
    from pmsm_hil.dashboards.replay import load_source, replay_to_rerun
    from pmsm_hil.hil.atomic_write import refuse_inputs

    if not args.mcap.is_file():
        raise DashboardError(f"hil replay: RUN.mcap {args.mcap} does not exist or is not a file")
    from pmsm_hil.hil.replay_canlog import is_can_log

    if is_can_log(args.mcap):
        return _replay_can_log(args)
    _refuse_non_mcap(args.mcap)
    if args.output is not None:
        return _replay_through_plant(args, args.mcap, None)
    targets = rerun_targets(args)
    if targets.save is not None:
        refuse_inputs(targets.save, [args.mcap], option="--rerun-save")
    if not targets.any():
        raise DashboardError("hil replay: choose --rerun, --rerun-save FILE.rrd or --rerun-serve")
    source = load_source(args.mcap, vdc=args.vdc)
    status = args.status_line
    status.phase("replaying into Rerun")
    status.total(len(source.periods), "periods")
    done = [0]

    def sent(block: np.ndarray) -> None:
        done[0] += len(block)
        status.update(done[0], f"sim {done[0] * source.ts_s:.3f}/{len(source.periods) * source.ts_s:.3f} s")

    rec, url = replay_to_rerun(source, targets, progress=sent)
    status.close("done")
    print(f"replayed {len(source.periods)} periods of {source.name}")
    if targets.save is not None:
        print(f"rerun: recording saved to {targets.save}")
    if url is not None:
        hold_serving(url)
    rec.disconnect()
    return 0


def _refuse_non_mcap(path: Path) -> None:
    """DashboardError (one line) unless `path` starts as an MCAP file: a .csv that is not python-can's CAN log
    (an empty file, a replay CSV of `hil plant replay`) or any other file is named as what it is."""
    from pmsm_hil.dashboards.errors import DashboardError
    from pmsm_hil.hil.runlog.reader import MAGIC

    with path.open("rb") as f:
        head = f.read(len(MAGIC))
    if head == MAGIC:
        return
    if path.suffix.lower() == ".csv":
        what = "is empty" if not head else "does not start with python-can's CSV header 'timestamp,arbitration_id,...'"
        raise DashboardError(f"hil replay: CSV {path} {what}: not a CAN log to replay (a replay CSV of switching "
                             "states goes to `hil plant replay --input`)")
    raise DashboardError(f"hil replay: {path} is neither an MCAP run log (bad magic) nor a CAN log "
                         "(.log, .asc, .blf, python-can .csv)")


def _motor(args: argparse.Namespace, default: str | None) -> MachineParams | None:
    from pmsm_hil.hil.motor_params import parse_set_options
    from pmsm_hil.hil.presets_loader import load_motor

    name = args.motor if args.motor is not None else default
    if name is None:
        if args.set_params:
            raise ParameterError("--set: give --motor too (the run's motor is rebuilt from its log as it ran)")
        return None
    return load_motor(name, parse_set_options(args.set_params))


def _replay_through_plant(args: argparse.Namespace, run_log: Path, capture: Path | None) -> int:
    """The run of `run_log` through the plant, its Commands from the log or the CAN log `capture`
    (src/pmsm_hil/hil/runner/replay_run.py)."""
    from pmsm_hil.hil.runner.replay_run import replay_run

    if targets_given(args):
        raise ParameterError("hil replay: --output replays through the plant, --rerun/--rerun-save/--rerun-serve into "
                             "the dashboard: choose one")
    if not run_log.is_file():
        raise ParameterError(f"--run-log {run_log}: does not exist or is not a file")
    for name in ("rpm", "ts", "theta0", "pwm_update"):
        if getattr(args, name) is not None:
            raise ParameterError(f"--{name.replace('_', '-')}: the run's set-up comes from its log {run_log}; the "
                                 "option is for a CAN log replayed without --run-log")
    done = replay_run(run_log, args.output, capture=capture, motor=_motor(args, None), allow_gaps=args.allow_gaps)
    r = done.result
    source = run_log if capture is None else capture
    extra = "".join([f"; {r.gaps} missing Command(s) held as the zero vector" if r.gaps else "",
                     f"; {r.run_misses} Command(s) the run did not apply replaced by its miss policy"
                     if r.run_misses else ""])
    print(f"replayed {r.commands} Commands of {source} through the plant over {r.periods} periods -> "
          f"{args.output}{extra}")
    if done.compared:
        off = "" if done.max_error_a <= REPRODUCED_A else (
            f" (more than {REPRODUCED_A:g} A: not this run's Commands, or a motor that differs from the run's)")
        print(f"largest |replayed - logged| phase current over the run's {done.compared} periods: "
              f"{done.max_error_a:.3g} A{off}")
    return 0


def targets_given(args: argparse.Namespace) -> bool:
    """True when any dashboard output (--rerun, --rerun-save, --rerun-serve) is asked for."""
    from pmsm_hil.dashboards.cli_live import rerun_targets

    return bool(rerun_targets(args).any())


def _replay_can_log(args: argparse.Namespace) -> int:
    """`hil replay CAPTURE.log`: the log's Commands through the plant (src/pmsm_hil/hil/replay.py), or as the run
    of --run-log ran them."""
    from pmsm_hil.hil.replay import replay

    if args.run_log is not None:
        if args.output is None:
            raise ParameterError(f"hil replay {args.mcap}: --output OUT.csv is required")
        return _replay_through_plant(args, args.run_log, args.mcap)
    for name in ("rpm", "ts", "output"):
        if getattr(args, name) is None:
            raise ParameterError(f"hil replay {args.mcap}: a CAN log is replayed through the plant: --{name} is "
                                 "required (with --rpm, --ts, --output; or --run-log RUN.mcap and --output)")
    args.status_line.phase("replaying Commands through the plant")
    r = replay(_motor(args, "niu2020-ipmsm"), rpm=args.rpm, ts_s=args.ts,  # type: ignore[arg-type]
               input_path=args.mcap, output_path=args.output, theta0_rad=args.theta0 or 0.0,
               allow_gaps=args.allow_gaps, pwm_update=args.pwm_update or "single")
    gaps = f"; {r.gaps} missing Command(s) held as the zero vector" if r.gaps else ""
    print(f"replayed {r.commands} Commands of {args.mcap} through the plant over {r.periods} periods -> "
          f"{args.output}{gaps}")
    return 0
