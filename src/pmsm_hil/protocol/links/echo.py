"""Echo peer for link tests and benchmarks: sends every received frame back.

Usage: python -m pmsm_hil.protocol.links.echo SPEC [--role target] [--idle-timeout S]
Prints "ready" once the link is open; stops on a frame with id STOP_ID or after S seconds idle.
"""

from __future__ import annotations

import argparse
import sys
import time

from pmsm_hil.protocol.errors import ProtocolError
from pmsm_hil.protocol.links.link import open_link

STOP_ID = 0x7FF


def serve(spec: str, role: str, idle_timeout_s: float) -> int:
    """Echo until the stop frame or an idle timeout; returns the number of frames echoed."""
    link = open_link(spec, "host" if role == "host" else "target")
    echoed = 0
    try:
        print("ready", flush=True)
        last = time.perf_counter()
        while time.perf_counter() - last < idle_timeout_s:
            fr = link.poll()
            if fr is None:
                continue
            last = time.perf_counter()
            if fr.arbitration_id == STOP_ID:
                break
            link.send([fr])
            echoed += 1
    finally:
        link.close()
    return echoed


def main(argv: list[str] | None = None) -> int:
    """Command-line entry; returns the exit code."""
    p = argparse.ArgumentParser(prog="python -m pmsm_hil.protocol.links.echo", description=__doc__.splitlines()[0])
    p.add_argument("spec")
    p.add_argument("--role", choices=("host", "target"), default="target")
    p.add_argument("--idle-timeout", type=float, default=10.0)
    args = p.parse_args(argv)
    try:
        serve(args.spec, args.role, args.idle_timeout)
    except ProtocolError as exc:
        print(f"echo: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
