"""`hil link-budget`: worst-case frames, bits and wire time per control period on a link."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from pmsm_hil.app.cli.board_budget import (
    BOARD_CLOCK_HZ,
    BUDGET_BOARDS,
    Turnaround,
    board_budget,
    firmware_elf,
    format_board_budget,
    measure_turnaround,
)
from pmsm_hil.protocol.errors import BudgetError
from pmsm_hil.protocol.links.budget import (
    COMMAND_FORMS,
    DEFAULT_BAUD,
    DEFAULT_BITRATE,
    DEFAULT_DATA_BITRATE,
    DEFAULT_ETHERNET_BITRATE,
    LINK_KINDS,
    LinkBudget,
    link_budget,
)

DEFAULT_RATE_HZ = 10_000.0


def add_parser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register the `link-budget` subcommand."""
    p = subparsers.add_parser(
        "link-budget",
        help="worst-case link budget of one control period",
        description="""Frames, worst-case bits (bit stuffing) and wire time per control period; bus load at --rate and
                       the maximum closed-loop rate.""",
        epilog="exit codes: 0 the link carries --rate, 1 too slow for --rate (the figures are still printed), "
        "2 bad arguments",
    )
    p.add_argument("--link", choices=LINK_KINDS, default="can", help="link type (default: %(default)s)")
    p.add_argument("--bitrate", type=int, default=None,
                   help=f"CAN (nominal) bit rate, bit/s (default {DEFAULT_BITRATE}); udp: the Ethernet bit rate "
                        f"(default {DEFAULT_ETHERNET_BITRATE})")
    p.add_argument("--data-bitrate", type=int, default=DEFAULT_DATA_BITRATE, help="CAN FD data bit rate, bit/s")
    p.add_argument("--baud", type=int, default=DEFAULT_BAUD, help="serial baud rate (8N1)")
    p.add_argument("--phases", type=int, choices=(3, 6), default=3, help="machine phases (default: %(default)s)")
    p.add_argument("--command", choices=COMMAND_FORMS, default=None,
                   help="Command form: switching states (CmdA/B/C, CmdFd) or duty cycles (CmdDutyA/B/C, CmdDutyFd) "
                        "(default: states; with --board and a measured firmware: the form it sends)")
    rate = p.add_mutually_exclusive_group()
    rate.add_argument("--rate", type=float, default=None, help=f"control rate, Hz (default: {DEFAULT_RATE_HZ:g})")
    rate.add_argument("--ts", type=float, default=None, metavar="S",
                      help="control period [s] instead of --rate (e.g. 25e-6: 40 kHz)")
    p.add_argument("--auth", action="store_true",
                   help="serial frames carry the 6-byte authentication trailer (on by default for spawned targets; "
                        "docs/protocol.md, 'Authenticated frames')")
    p.add_argument("--board", choices=BUDGET_BOARDS, default=None,
                   help="add the firmware's time on this MCU (its instructions on the virtual board, CPI 1) to the "
                        "wire time: the achievable rate of a bench with that board (--link can or canfd)")
    p.add_argument("--firmware", type=Path, default=None, metavar="PATH",
                   help="with --board: the firmware, an ELF built by `hil fw build --board BOARD --src DIR` or its "
                        "source folder (default: the template examples/my_firmware)")
    p.add_argument("--instructions", type=int, default=None, metavar="N",
                   help="with --board: the MCU's cycles per period (Measurement in to Command out) instead of "
                        "measuring them")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run)


def format_budget(b: LinkBudget) -> str:
    """Human-readable table."""
    rate = f"{b.rate_hz:.0f} Hz" if b.rate_hz is not None else "-"
    load = f"{b.bus_load_pct:.1f} %" if b.bus_load_pct is not None else "-"
    if b.link == "can":
        speed = f"{b.bitrate} bit/s"
    elif b.link == "canfd":
        speed = f"{b.bitrate} / {b.data_bitrate} bit/s"
    elif b.link == "udp":
        speed = f"Ethernet {b.bitrate} bit/s; the host's network stack excluded"
    else:
        speed = f"{b.baud} Bd 8N1" + (", authenticated frames" if b.auth else "")
    lines = [
        f"link {b.link} ({speed}), {b.phases} phases",
        f"  up   (measurement): {b.frames_per_period_up} frame(s), payload {list(b.payloads_up)} B, "
        f"{b.bits_up_worst} bits worst, {b.wire_time_up_us:.1f} µs",
        f"  down (command):     {b.frames_per_period_down} frame(s), payload {list(b.payloads_down)} B, "
        f"{b.bits_down_worst} bits worst, {b.wire_time_down_us:.1f} µs",
        f"  per period: {b.bits_per_period_worst} bits, {b.wire_time_per_period_us:.1f} µs on the wire",
        f"  bus load at {rate}: {load}" + ("" if b.feasible is None else "  (fits)" if b.feasible else "  (TOO SLOW)"),
        f"  max closed-loop rate (compute time excluded): {b.max_rate_hz:.0f} Hz",
    ]
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    """Print the budget; returns 0 if the link carries --rate, 1 if it is too slow (BudgetError on invalid
    arguments: `hil` prints it as one line, exit 2)."""
    if args.board is None and (args.firmware is not None or args.instructions is not None):
        raise BudgetError("--firmware and --instructions go with --board (the MCU whose time they give)")
    if args.ts is not None and not (math.isfinite(args.ts) and args.ts > 0):
        raise BudgetError(f"--ts must be a positive number of seconds, got {args.ts!r}")
    rate_hz = 1.0 / args.ts if args.ts is not None else DEFAULT_RATE_HZ if args.rate is None else args.rate
    bitrate = args.bitrate if args.bitrate is not None else \
        DEFAULT_ETHERNET_BITRATE if args.link == "udp" else DEFAULT_BITRATE
    b = link_budget(
        args.link,
        args.phases,
        bitrate=bitrate,
        data_bitrate=args.data_bitrate,
        baud=args.baud,
        rate_hz=rate_hz,
        auth=args.auth,
        command=args.command or "states",
    )
    if args.board is not None:
        return _run_board(args, b)
    print(json.dumps(b.as_dict(), indent=1) if args.json else format_budget(b))
    if b.feasible is False:
        asked = f"--ts {args.ts:g} s is {b.rate_hz:.0f} Hz" if args.ts is not None else f"--rate is {b.rate_hz:.0f} Hz"
        print(f"hil: link-budget: too slow: {b.link} carries at most {b.max_rate_hz:.0f} Hz of closed loop, {asked}: "
              f"{b.frames_per_period_up} + {b.frames_per_period_down} frames per period need "
              f"{b.wire_time_per_period_us:.1f} µs on the wire (worst case)", file=sys.stderr)
        return 1
    return 0


def _turnaround(args: argparse.Namespace) -> Turnaround:
    if args.instructions is not None:
        if args.instructions <= 0:
            raise BudgetError(f"--instructions must be a positive number of cycles, got {args.instructions}")
        if args.firmware is not None:
            raise BudgetError("--instructions and --firmware: give one (--instructions skips the measurement)")
        n = float(args.instructions)
        return Turnaround("(given)", n, n, BOARD_CLOCK_HZ[args.board], "given")
    elf = firmware_elf(args.board, args.firmware)
    label = str(args.firmware if args.firmware is not None else "examples/my_firmware")
    return measure_turnaround(args.board, elf, label=label)


def _run_board(args: argparse.Namespace, b: LinkBudget) -> int:
    """The budget with the MCU's turnaround: exit 0 when --rate fits, 1 when it does not."""
    if b.link not in ("can", "canfd"):
        raise BudgetError(f"--board {args.board}: its board layer carries the frames on FDCAN1, use --link can or "
                          f"canfd, got --link {args.link}")
    turnaround = _turnaround(args)
    form = turnaround.command_form
    if args.command is None and form is not None and form != "states":  # the Command form the firmware sends
        b = link_budget(b.link, b.phases, bitrate=b.bitrate, data_bitrate=b.data_bitrate, baud=b.baud,
                        rate_hz=b.rate_hz, auth=b.auth, command=form)
    bb = board_budget(args.board, b, turnaround)
    if args.json:
        print(json.dumps({**b.as_dict(), "with_board": bb.as_dict()}, indent=1))
    else:
        print(format_budget(b))
        print(format_board_budget(bb))
    if bb.feasible is False:
        print(f"hil: link-budget: too slow: {b.link} with {args.board} running {bb.turnaround.firmware} carries at "
              f"most {bb.max_rate_hz:.0f} Hz of closed loop, asked {b.rate_hz:.0f} Hz", file=sys.stderr)
        return 1
    return 0
