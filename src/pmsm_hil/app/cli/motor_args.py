"""Shared motor arguments (--motor, --set) of every command that takes a motor."""

from __future__ import annotations

import argparse

from pmsm_hil.hil.machine_params import MachineParams
from pmsm_hil.hil.motor_params import SETTABLE_UNITS, parse_set_options
from pmsm_hil.hil.presets_loader import load_motor, preset_names

_SET_HELP = "override a motor parameter (SI units): " + ", ".join(
    f"{k} [{u}]" if u else k for k, u in SETTABLE_UNITS.items())


def add_motor_arguments(parser: argparse.ArgumentParser, default: str | None = "niu2020-ipmsm", *,
                        shown_default: str | None = None) -> None:
    """Add --motor PRESET|FILE and repeatable --set NAME=VALUE. `shown_default`: the default --help names when
    `default` is None because a later layer (a config file) supplies it; neither: --motor is required."""
    shown = default or shown_default
    parser.add_argument("--motor", default=default, metavar="PRESET|FILE",
                        help=f"bundled preset ({', '.join(preset_names())}) or a TOML motor file "
                             + (f"(default {shown})" if shown else "(required)"))
    parser.add_argument("--set", dest="set_params", action="append", default=[], metavar="NAME=VALUE",
                        help=_SET_HELP)


def motor_from_args(args: argparse.Namespace) -> MachineParams:
    """Load the motor named by --motor with the --set overrides applied."""
    return load_motor(args.motor, parse_set_options(args.set_params))
