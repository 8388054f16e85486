"""A local UDP flood: junk datagrams from another socket to the given ports, paced at RATE datagrams/s in all
(round robin), until SIGTERM or SECONDS have passed; prints "sent N in T s" when it stops.

Usage: python udp_flood.py PORT[,PORT...] RATE SECONDS
"""

from __future__ import annotations

import contextlib
import signal
import socket
import sys
import time
from types import FrameType

JUNK = bytes(24)  # a datagram no hiludp end accepts (no session, no valid length)


def main() -> int:
    ports = [int(p) for p in sys.argv[1].split(",")]
    rate, seconds = float(sys.argv[2]), float(sys.argv[3])
    stop = {"flag": False}

    def on_term(signum: int, frame: FrameType | None) -> None:
        stop["flag"] = True

    signal.signal(signal.SIGTERM, on_term)
    addrs = [("127.0.0.1", p) for p in ports]
    sent = 0
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        print("flooding", flush=True)
        t0 = time.perf_counter()
        while not stop["flag"] and (now := time.perf_counter() - t0) < seconds:
            due = int(now * rate)
            while sent < due:
                with contextlib.suppress(OSError):  # an ICMP error reported back: the flood goes on
                    sock.sendto(JUNK, addrs[sent % len(addrs)])
                sent += 1
            time.sleep(0.0005)
        print(f"sent {sent} in {time.perf_counter() - t0:.3f} s", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
