"""`hil replay RUN.mcap`: a recorded run into the Rerun dashboard (viewer, .rrd file or web viewer);
`hil replay CAPTURE.log --rpm N --ts S --output OUT.csv`: the Commands of a CAN log (candump -L .log, .asc, .blf,
python-can .csv) through the plant offline, as `hil plant replay` (a bench capture replayed against the plant)."""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from pmsm_hil.app.cli.motor_args import add_motor_arguments
from pmsm_hil.app.cli.parsing import finite_float, positive_float


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `hil replay`."""
    from pmsm_hil.dashboards.cli_live import add_rerun_arguments

    p = subparsers.add_parser("replay", help="replay a recorded run (MCAP) into the Rerun dashboard",
                              description="""Any run.mcap of `hil run` into the same blueprint as the live dashboard.
                                             Give --rerun, --rerun-save FILE.rrd and/or --rerun-serve. A CAN log instead
                                             (.log candump -L, .asc, .blf, python-can .csv, e.g. from `hil mcap
                                             export`): its Commands drive the plant offline at a held speed (--rpm,
                                             --ts, --output; as `hil plant replay`).""")
    p.add_argument("mcap", type=Path, metavar="RUN.mcap|CAPTURE.log",
                   help="run log written by `hil run`, or a CAN log whose Commands to replay through the plant")
    p.add_argument("--vdc", type=positive_float("--vdc"), help="DC-link voltage [V] (default: the run's motor)")
    add_rerun_arguments(p)
    can_log = p.add_argument_group("a CAN log through the plant (offline plant replay)")
    add_motor_arguments(can_log, default="niu2020-ipmsm")  # type: ignore[arg-type]
    can_log.add_argument("--rpm", type=finite_float("--rpm"), help="held shaft speed [rpm]")
    can_log.add_argument("--ts", type=positive_float("--ts"), help="control period of the capture [s]")
    can_log.add_argument("--theta0", type=finite_float("--theta0"), default=0.0, help="initial electrical angle [rad]")
    can_log.add_argument("--output", type=Path, help="output CSV (t, currents, torque, angle, speed per period)")
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


def _replay_can_log(args: argparse.Namespace) -> int:
    """`hil replay CAPTURE.log`: the log's Commands through the plant (src/pmsm_hil/hil/replay.py)."""
    from pmsm_hil.app.cli.motor_args import motor_from_args
    from pmsm_hil.hil.errors import ParameterError
    from pmsm_hil.hil.replay import replay

    for name in ("rpm", "ts", "output"):
        if getattr(args, name) is None:
            raise ParameterError(f"hil replay {args.mcap}: a CAN log is replayed through the plant: --{name} is "
                                 "required (with --rpm, --ts, --output)")
    args.status_line.phase("replaying Commands through the plant")
    n = replay(motor_from_args(args), rpm=args.rpm, ts_s=args.ts, input_path=args.mcap, output_path=args.output,
               theta0_rad=args.theta0)
    print(f"replayed {n} Commands of {args.mcap} through the plant -> {args.output}")
    return 0
