"""`hil plant replay`: replay recorded switching commands through the plant model offline."""

from __future__ import annotations

import argparse
from pathlib import Path

from pmsm_hil.app.cli.motor_args import add_motor_arguments, motor_from_args
from pmsm_hil.app.cli.parsing import finite_float
from pmsm_hil.hil.errors import ParameterError


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `replay` under `hil plant`."""
    p = subparsers.add_parser("replay", help="replay a CSV of switching commands in dyno mode",
                              description="""Replay switching commands (sa,sb,sc or s0,t0,s1,t1,s2,t2 rows) through the
                                             plant at a held speed; writes t,i_a,...,omega_m. A dual three-phase motor
                                             (lls > 0) takes sa1,sb1,sc1,sa2,sb2,sc2 or 6-bit codes 0..63 [S_A S_B S_C
                                             S_U S_V S_W] and writes
                                             t,i_a1,...,i_c2,i_d,i_q,i_x,i_y,torque,theta_e,omega_m.""")
    add_motor_arguments(p, default=None)
    p.add_argument("--rpm", type=finite_float("--rpm"), required=True, help="held shaft speed [rpm]")
    p.add_argument("--ts", type=finite_float("--ts"), required=True, help="control period [s]")
    p.add_argument("--theta0", type=finite_float("--theta0"), default=0.0, help="initial electrical angle [rad]")
    p.add_argument("--input", type=Path, required=True, help="input CSV")
    p.add_argument("--output", type=Path, required=True, help="output CSV")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute `hil plant replay`."""
    if args.motor is None:
        raise ParameterError("--motor is required (a preset name or a TOML file)")
    from pmsm_hil.hil.replay import replay  # the plant and numpy: imported when a replay runs

    params = motor_from_args(args)
    result = replay(params, rpm=args.rpm, ts_s=args.ts, input_path=args.input, output_path=args.output,
               theta0_rad=args.theta0)
    print(f"replayed {result.periods} periods -> {args.output}")
    return 0
