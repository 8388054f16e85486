"""A local UDP flood: junk datagrams from another socket to the given ports, paced at RATE datagrams/s in all
(round robin), until SIGTERM or SECONDS have passed; prints "sent N in T s" when it stops.

Usage: python udp_flood.py PORT[,PORT...] RATE SECONDS
"""

from __future__ import annotations

import contextlib
import itertools
import socket
import sys

from udp_pacing import Pacer

JUNK = bytes(24)  # a datagram no hiludp end accepts (no session, no valid length)


def main() -> int:
    ports = [int(p) for p in sys.argv[1].split(",")]
    rate, seconds = float(sys.argv[2]), float(sys.argv[3])
    pacer = Pacer()
    targets = itertools.cycle([("127.0.0.1", p) for p in ports])  # round robin
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))

        def send(owed: int) -> int:
            for _ in range(owed):
                with contextlib.suppress(OSError):  # an ICMP error reported back: the flood goes on
                    sock.sendto(JUNK, next(targets))
            return owed

        return pacer.run(seconds, rate, 0.0005, send, "flooding", "sent")


if __name__ == "__main__":
    sys.exit(main())
