"""A privileged local spoofer (needs CAP_NET_RAW): captures the hiludp data datagrams between two local ports on
the loopback interface and injects, from a raw socket with the genuine source address and port, replays of the
latest genuine datagram of each direction, forged copies (a payload byte changed, the CRC-16 fixed) and copies
stripped of the authentication trailer (CRC fixed), paced at RATE datagrams/s, until SIGTERM or SECONDS.
Prints "capturing" once ready and "injected N in T s" when it stops.

Usage: python udp_spoof.py PORT_A PORT_B RATE SECONDS
"""

from __future__ import annotations

import binascii
import socket
import struct
import sys

from udp_pacing import Pacer

ETH_P_ALL = 0x0003
TRAILER = 6  # freshness 2 + MAC 4 (src/pmsm_hil/protocol/links/auth.py)


def _udp(src: int, dst: int, payload: bytes) -> bytes:
    """IPv4 + UDP headers (checksums 0: the kernel fills the IP one; a UDP checksum of 0 means none) + payload."""
    udp = struct.pack("!HHHH", src, dst, 8 + len(payload), 0) + payload
    lo = socket.inet_aton("127.0.0.1")
    return struct.pack("!BBHHHBBH4s4s", 0x45, 0, 20 + len(udp), 0, 0, 64, socket.IPPROTO_UDP, 0, lo, lo) + udp


def _with_crc(dgram: bytes) -> bytes:
    return dgram + binascii.crc_hqx(dgram[4:], 0xFFFF).to_bytes(2, "big")


def _variants(genuine: bytes) -> list[bytes]:
    """The replay, a forged copy and a copy without the trailer of one genuine data datagram."""
    forged = bytearray(genuine[:-2])
    forged[4 + 7] ^= 0x5A  # the first payload byte
    stripped = genuine[:-2 - TRAILER]
    return [genuine, _with_crc(bytes(forged)), _with_crc(stripped)]


def main() -> int:
    a, b = int(sys.argv[1]), int(sys.argv[2])
    rate, seconds = float(sys.argv[3]), float(sys.argv[4])
    pacer = Pacer()
    cap = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL))
    cap.bind(("lo", 0))
    cap.setblocking(False)
    raw = socket.socket(socket.AF_INET, socket.SOCK_RAW, socket.IPPROTO_RAW)
    latest: dict[tuple[int, int], bytes] = {}

    def send(owed: int) -> int:
        while True:
            try:
                pkt = cap.recv(65536)
            except BlockingIOError:
                break
            ip = pkt[14:]
            if len(ip) < 28 or ip[9] != socket.IPPROTO_UDP:
                continue
            ihl = (ip[0] & 0x0F) * 4
            src, dst = struct.unpack_from("!HH", ip, ihl)
            payload = ip[ihl + 8:]
            ours = struct.unpack_from("!H", ip, ihl + 6)[0] == 0  # what this spoofer sent (no UDP checksum)
            if {src, dst} == {a, b} and not ours and len(payload) > 13 + TRAILER and payload[:4] != b"\0\0\0\0":
                latest[(src, dst)] = payload
        out = [(src, dst, dgram) for (src, dst), genuine in latest.items() for dgram in _variants(genuine)][:owed]
        for src, dst, dgram in out:
            raw.sendto(_udp(src, dst, dgram), ("127.0.0.1", 0))
        return len(out)

    return pacer.run(seconds, rate, 0.0002, send, "capturing", "injected")


if __name__ == "__main__":
    sys.exit(main())
