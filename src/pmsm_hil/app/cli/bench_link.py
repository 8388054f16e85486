"""`hil bench link`: codec cost per frame (Python vs cantools) and round-trip latency per link."""

from __future__ import annotations

import argparse
import json
import os
import socket
import statistics
import sys
import time
import tty
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.protocol.codec import PROFILES, FrameCodec
from pmsm_hil.protocol.errors import ProtocolError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.layout import load_database
from pmsm_hil.protocol.links.peer import EchoPeer
from pmsm_hil.protocol.messages import Command, Measurement

if TYPE_CHECKING:  # the links (python-can) are imported where one is opened, not for the parser
    from pmsm_hil.protocol.links.link import Link

_BENCH_FRAME = Frame(0x108, bytes(range(16)), True)  # CAN FD, 16 bytes: the round-trip payload


def _free_udp_port() -> int:
    """A UDP port on 127.0.0.1 that is free now (two benches or tests may run at once)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def add_parser(subparsers: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    """Register the `link` bench subcommand (under `hil bench`)."""
    p = subparsers.add_parser(
        "link",
        help="codec cost and link round-trip latency",
        description="""Encode/decode cost per frame (Python codec vs cantools) and round-trip latency over virtual, UDP
                       and serial (pty) links.""",
    )
    p.add_argument("--repeats", type=int, default=7, help="timing repeats (median reported)")
    p.add_argument("--count", type=int, default=2000, help="operations / round trips per repeat")
    p.add_argument("--links", default="virtual,udp,serial", help="comma-separated subset of virtual,udp,serial")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=run)


def _per_op_ns(fn: Callable[[], Any], count: int, repeats: int, per_call: int = 1) -> float:
    samples = []
    for _ in range(repeats):
        t0 = time.perf_counter_ns()
        for _ in range(count):
            fn()
        samples.append((time.perf_counter_ns() - t0) / (count * per_call))
    return statistics.median(samples)


def _profile_costs(profile: str, count: int, repeats: int) -> dict[str, float]:
    db = load_database()
    codec = FrameCodec(profile)  # type: ignore[arg-type]
    meas = Measurement(7, 1.234, -0.617, -0.617, 1.0, 104.72, 48.0, 0)
    cmd = Command(7, (4, 6, 7), (30000, 20000, 50000), 12, 27, 1234, 0)
    frames = codec.encode(meas) + codec.encode(cmd)
    n = len(frames)
    stream = [
        fr
        for k in range(count)
        for m in (
            Measurement(k & 0xFFFF, 1.0, 2.0, 3.0, 1.0, 10.0, 48.0, 0),
            Command(k & 0xFFFF, (4, 6, 7), (1, 2, 3), 1, 2, 3, 0),
        )
        for fr in codec.encode(m)
    ]
    dec_samples = []
    for _ in range(repeats):
        feed = codec.decoder().feed
        t0 = time.perf_counter_ns()
        for fr in stream:
            feed(fr)
        dec_samples.append((time.perf_counter_ns() - t0) / len(stream))
    msgs = [db.get_message_by_frame_id(fr.arbitration_id) for fr in frames]
    decoded = [m.decode(fr.data) for m, fr in zip(msgs, frames, strict=True)]

    def py_encode() -> None:
        codec.encode(meas)
        codec.encode(cmd)

    def ct_encode() -> None:
        for m, d in zip(msgs, decoded, strict=True):
            m.encode(d)

    def ct_decode() -> None:
        for m, fr in zip(msgs, frames, strict=True):
            m.decode(fr.data)

    slow = max(1, count // 4)
    return {
        "python_encode_ns_per_frame": _per_op_ns(py_encode, count, repeats, n),
        "python_decode_ns_per_frame": statistics.median(dec_samples),
        "cantools_encode_ns_per_frame": _per_op_ns(ct_encode, slow, repeats, n),
        "cantools_decode_ns_per_frame": _per_op_ns(ct_decode, slow, repeats, n),
    }


def codec_costs(count: int, repeats: int) -> dict[str, dict[str, float]]:
    """ns per frame: Python encode/decode and cantools encode/decode, for each profile."""
    return {profile: _profile_costs(profile, count, repeats) for profile in PROFILES}


def _rtt_summary(rtts_us: list[float]) -> dict[str, float]:
    """Median and p99 (µs) of the round-trip times `rtts_us`, and their count."""
    rtts_us = sorted(rtts_us)
    return {
        "median_us": rtts_us[len(rtts_us) // 2],
        "p99_us": rtts_us[int(len(rtts_us) * 0.99) - 1],
        "count": float(len(rtts_us)),
    }


def _round_trips(link: Link, count: int, echo: Link | None = None) -> dict[str, float]:
    """Round trips [µs] of one frame sent on `link` and answered by a peer process, or by `echo` (the other end
    in this process, which sends back what it receives)."""
    lost = "round trip timed out after 1 s" if echo is None else "virtual round trip lost a frame"
    frame = _BENCH_FRAME
    rtts = []
    for _ in range(count):
        t0 = time.perf_counter_ns()
        link.send([frame])
        if echo is not None:
            got = echo.recv(1.0)
            if got is None:
                raise ProtocolError(lost)
            echo.send([got])
        if link.recv(1.0) is None:
            raise ProtocolError(lost)
        rtts.append((time.perf_counter_ns() - t0) / 1000.0)
    return _rtt_summary(rtts)


def _virtual(count: int) -> dict[str, float]:
    from pmsm_hil.protocol.links.link import open_link

    host = open_link("virtual:bench_link", "host")
    target = open_link("virtual:bench_link", "target")
    try:
        return _round_trips(host, count, echo=target)
    finally:
        host.close()
        target.close()


def _with_peer(spec_local: str, spec_peer: str, count: int, pass_fds: tuple[int, ...] = ()) -> dict[str, float]:
    from pmsm_hil.protocol.links.echo import STOP_ID
    from pmsm_hil.protocol.links.link import open_link

    with EchoPeer(spec_peer, pass_fds=pass_fds):
        link = open_link(spec_local, "host")
        try:
            _round_trips(link, min(count, 50))  # warm-up
            return _round_trips(link, count)
        finally:
            link.send([Frame(STOP_ID, b"", False)])
            link.close()


def link_latencies(links: list[str], count: int) -> dict[str, dict[str, float]]:
    """Round-trip latency (µs) per link; UDP and serial echo from another process."""
    out: dict[str, dict[str, float]] = {}
    if "virtual" in links:
        out["virtual (one thread)"] = _virtual(count)
    if "udp" in links:
        a, b = _free_udp_port(), _free_udp_port()
        out["udp (peer process)"] = _with_peer(f"udp:{a}:{b}", f"udp:{b}:{a}", count)
    if "serial" in links:
        master, slave = os.openpty()
        tty.setraw(slave)
        name = os.ttyname(slave)
        try:
            out["serial pty (peer process)"] = _with_peer(f"serial:{name}", f"serial:fd:{master}", count, (master,))
        finally:
            os.close(master)
            os.close(slave)
    return out


def run(args: argparse.Namespace) -> int:
    """Run the benchmark and print it; returns 0, or 1 if a link failed."""
    links = [s.strip() for s in args.links.split(",") if s.strip()]
    unknown = sorted(set(links) - {"virtual", "udp", "serial"})
    if unknown:
        raise ParameterError(f"--links: unknown link(s) {', '.join(unknown)} (known: virtual, udp, serial)")
    if args.count < 1 or args.repeats < 1:
        raise ParameterError(f"--count/--repeats must be ≥ 1, got {args.count}/{args.repeats}")
    result: dict[str, Any] = {"codec": codec_costs(args.count, args.repeats)}
    try:
        result["round_trip"] = link_latencies(links, args.count)
    except ProtocolError as exc:
        print(f"hil: error: bench link: {exc}", file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps(result, indent=1))
        return 0
    print("codec cost per frame (ns, median):")
    for profile, costs in result["codec"].items():
        print(f"  {profile:6s} " + "  ".join(f"{k.replace('_ns_per_frame', '')}={v:.0f}" for k, v in costs.items()))
    print("round trip (µs):")
    for name, r in result["round_trip"].items():
        print(f"  {name:28s} median {r['median_us']:.1f}  p99 {r['p99_us']:.1f}")
    return 0
