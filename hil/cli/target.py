"""`hil target`: run the virtual target (firmware stub) in its own process on a link."""

from __future__ import annotations

import argparse


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `hil target`."""
    p = subparsers.add_parser("target", help="run the virtual target on a link (its own process)",
                              description="Serve the C reference firmware over a link until SIGTERM/Ctrl-C. "
                                          "The host selects the controller with its setpoint; --controller "
                                          "preselects one.")
    p.add_argument("--link", required=True, help="link SPEC, e.g. udp:..., serial:/dev/pts/3, socketcan:can0")
    p.add_argument("--controller", help="controller to preselect (e.g. mpcc)")
    p.add_argument("--role", default="target", choices=("target", "host"),
                   help="end of a point-to-point link this process takes (default target)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    """Execute `hil target`."""
    from pmsm_hil.sim_target.process import serve

    target = serve(args.link, args.controller, role=args.role)
    c = target.counters
    print(f"target stopped: {c.measurements} measurements, {c.commands} commands, "
          f"{c.config_writes} config writes ({c.config_rejected} rejected), {c.faults} faults")
    return 0
