"""The native loop over a serial link (src/pmsm_hil/hil/runner/c/links/loop_serial.c: COBS + CRC-16 framing of
firmware_stub/target/hil_serial.c) with the native target it spawns on the other end of a pty (`hil target
--native`, src/pmsm_hil/hil/runner/c/target_serve.c) gives the records, frames and metrics of the Python loop with the
Python target over the same kind of link, bit for bit (but what the wall clock measures); against a foreign target it
ends runs as the Python loop does; its receiver counts a damaged byte stream as the hilserial bus does, and drives the
bus's own C state (link sequence numbers, a packet half received) between Python's sends and receives."""

from __future__ import annotations

import binascii
import contextlib
import os
import socket
import struct
import subprocess
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from pmsm_hil.hil.runlog.reader import read_frames, read_periods
from pmsm_hil.hil.runner.run import RunResult, run_closed_loop
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.runner.wire import COUNTERS, WireHandle
from pmsm_hil.hil.runner.wire_serial import SERIAL_WIRE
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links import open_link
from tests.protocol.wire_oracle import cobs_decode, cobs_encode
from tests.runner.test_dut_contract import _run
from tests.runner.test_loop import SENSORS, _assert_same_frames, _mirrored, _six, _three
from tests.runner.test_wire_udp import WALL_METRICS, _assert_same


def _pair(cfg: RunConfig, tmp_path: Path | None = None) -> tuple[RunResult, RunResult]:
    """The Python loop + Python target, then the native loop + native target, each spawned on a new pty, at the
    default lockstep timeout (test_wire_udp._pair says why it holds)."""
    runs = []
    for loop in ("python", "native"):
        out = None if tmp_path is None else tmp_path / loop
        runs.append(run_closed_loop(replace(cfg, target="spawn", loop=loop, out_dir=out)))
    py, na = runs
    assert py.metrics["loop"] == "python" and na.metrics["loop"] == "native" and na.metrics["loop_note"] is None
    return py, na


def test_three_phase_canfd_with_sensors_and_a_speed_step_over_a_pty(tmp_path: Path) -> None:
    py, na = _pair(_three(sensors=SENSORS, link="serial:pty"), tmp_path)
    _assert_same(py, na)
    assert py.mcap_path is not None and na.mcap_path is not None
    _assert_same_frames(read_frames(py.mcap_path), read_frames(na.mcap_path))


@pytest.mark.parametrize(("make", "link"), [(_three, "serial:pty,fd=false"), (_mirrored, "serial:pty"),
                                            (_six, "serial:pty,fd=false")])
def test_classic_can_mirrored_and_six_phases_over_a_pty(make: Any, link: str) -> None:
    py, na = _pair(make(link=link))
    _assert_same(py, na)


@pytest.mark.parametrize("rules", [("bad_sum=30",), ("bad_state=30",), ("silent=30",)])
def test_a_foreign_target_breaking_the_contract_ends_both_loops_alike(rules: tuple[str, ...], tmp_path: Path) -> None:
    """Two violations and a silent target (watchdog) from the foreign target of test_dut_contract.py (python-can
    + cantools on the pty's other end): the same ending, findings, records and metrics from both loops, and the
    target received the disabling Setpoint last from each. (Its FaultTarget comes after the period's Command,
    so the period that sees it depends on timing in either loop: test_dut_contract.py checks that ending.)"""
    # the silent target: _run's lockstep timeout (at 0.05 s a 50 ms stall of the target process on a loaded
    # machine would be an extra finding in one loop only); the violations need no short timeout: 10 s, so that a
    # loaded machine's stall of the foreign target (a Python process, its time not visible to the runner) is waited
    extra = (("--tolerate", "100", "--watchdog-periods", "3") if "silent" in rules[0]
             else ("--lockstep-timeout", "10"))
    ended = []
    for loop in ("python", "native"):
        master, slave = os.openpty()
        try:
            e = _run(tmp_path / loop, (master, os.ttyname(slave)), *rules, extra=(*extra, "--loop", loop))
        finally:
            os.close(slave)
            with contextlib.suppress(OSError):
                os.close(master)
        assert e.metrics["loop"] == loop
        e.check_safe_and_complete()
        ended.append(e)
    py, na = ended
    assert py.rc == na.rc != 0 and py.metrics["end_reason"] == na.metrics["end_reason"]
    assert py.metrics["dut_violation_list"] == na.metrics["dut_violation_list"]
    assert py.setpoints() == na.setpoints() == [1, 0]
    a, b = read_periods(py.out / "run.mcap"), read_periods(na.out / "run.mcap")
    assert a.shape == b.shape and a.shape[0] > 0
    for name in a.dtype.names or ():
        assert a[name].tobytes() == b[name].tobytes(), name
    # the foreign target starts beside the host: how often the configuration is resent, and the echo of a pty
    # not yet in raw mode, depend on its start-up time, so the link counters are not compared
    assert py.metrics.keys() == na.metrics.keys()
    for key in py.metrics.keys() - WALL_METRICS - {"link"}:
        assert py.metrics[key] == na.metrics[key], key


def _packet(arb: int, data: bytes, seq: int, flags: int = 0, crc_delta: int = 0, length: int | None = None) -> bytes:
    body = struct.pack("<IBBB", arb, flags, seq & 0xFF, len(data) if length is None else length) + data
    crc = (binascii.crc_hqx(body, 0xFFFF) + crc_delta) & 0xFFFF
    return cobs_encode(body + crc.to_bytes(2, "big")) + b"\x00"


def _damaged_stream() -> bytes:
    """Good frames among every kind of damage the deframer and the link seq check count."""
    return b"".join([
        b"\x00",  # an empty packet: nothing
        _packet(0x180, bytes(range(1, 13)), 0, flags=3),  # FD, 12 bytes
        _packet(0x181, b"\x01\x02", 1),  # classic
        _packet(0x180, bytes(12), 2, flags=3, crc_delta=1),  # CRC error
        b"\x05\x01\x00",  # COBS block past the end: framing error
        b"\x02\x01\x00",  # too short for a header: framing error
        bytes([7] * 200) + b"\x00",  # no delimiter for more than a packet can be: framing error
        _packet(0x181, b"\x03", 3, length=2),  # length field disagrees: framing error
        _packet(0x181, bytes(9), 4, flags=1),  # 9 bytes is no FD length: framing error
        _packet(0x181, b"\x04", 5),
        _packet(0x181, b"\x04", 5),  # duplicate
        _packet(0x181, b"\x05", 8),  # 6, 7 dropped (and 2, 3, 4 before)
        _packet(0x181, b"\x06", 9, flags=0x08),  # extended id: ignored (after the seq check)
        _packet(0x181, b"\x07", 2),  # out of order, still delivered
        _packet(0x181, b"\x08" * 8, 10)[:-4],  # a packet half received at the end
    ])


def _serial_state(ffi: Any, fd: int) -> Any:
    s = ffi.new("nl_serial_t *")
    s.fd, s.fd_frames, s.rx_last, s.write_timeout_ns = fd, 1, -1, 1_000_000_000
    return s


def test_the_loops_receiver_counts_a_damaged_stream_as_the_serial_bus() -> None:
    from pmsm_hil.hil._loop_native import ffi, lib

    stream = _damaged_stream()
    got: dict[str, tuple[list[tuple[int, bytes, bool]], dict[str, int]]] = {}
    for who in ("bus", "loop"):
        a, b = socket.socketpair()
        with a, b:
            b.setblocking(False)
            a.sendall(stream)
            frames = []
            if who == "bus":
                link = open_link(f"serial:fd:{os.dup(b.fileno())}", "host")
                with link:
                    while (fr := link.recv(0.05)) is not None:
                        frames.append((fr.arbitration_id, fr.data, fr.is_fd))
                    stats = link.stats.as_dict()
            else:
                s = _serial_state(ffi, b.fileno())
                f = ffi.new("hil_core_frame_t *")
                while lib.nl_serial_recv(s, f, lib_deadline(0.05)) > 0:
                    frames.append((int(f.id), bytes(ffi.buffer(f.data, f.len)), bool(f.fd)))
                    assert not any(f.data[f.len:64])  # the payload past len is zeroed (frame records)
                stats = {name: int(getattr(s.stats, name)) for name in COUNTERS}
                assert s.pkt_n == len(_packet(0x181, b"\x08" * 8, 10)) - 4 and s.rx_last == 9
        got[who] = frames, stats
    assert got["loop"] == got["bus"]
    frames, stats = got["loop"]
    assert [f[0] for f in frames] == [0x180, 0x181, 0x181, 0x181, 0x181]
    assert (stats["crc_errors"], stats["framing_errors"], stats["duplicate"], stats["dropped"],
            stats["out_of_order"], stats["ignored"], stats["frames_rx"]) == (1, 5, 1, 5, 1, 1, 6)


def lib_deadline(seconds: float) -> int:
    """A CLOCK_MONOTONIC deadline `seconds` from now [ns] (the C links' clock)."""
    return time.clock_gettime_ns(time.CLOCK_MONOTONIC) + int(seconds * 1e9)


def test_the_loop_drives_the_serial_buss_own_state_between_pythons_frames() -> None:
    """The loop's nl_serial_send writes what the bus's fast path writes, continuing its link sequence (an FD
    frame on a classic link is a send error counted on the bus); a packet half received by the bus is completed
    by the loop's receive and one half received by the loop by the bus's (SERIAL_WIRE: one C state, no hand-over);
    the counters are the bus's."""
    from pmsm_hil.hil._loop_native import ffi, lib

    a, b = socket.socketpair()
    with a, b:
        a.setblocking(False)
        host = open_link(f"serial:fd:{os.dup(b.fileno())}", "host")
        with host:
            bus = host.bus
            host.send([Frame(0x100, b"\x01\x00\x02", False)])
            python_bytes = a.recv(4096)
            assert cobs_decode(python_bytes[:-1])[4:7] == b"\x00\x00\x03"  # flags 0, link seq 0, 3 bytes
            h = WireHandle(SERIAL_WIRE, ffi, lib, bus, target_role=False)
            out = ffi.new("hil_core_frame_t *", {"id": 0x100, "len": 3, "fd": 0, "data": b"\x01\x00\x02"})
            assert lib.nl_serial_send(h.state, out) == 0
            c_bytes = a.recv(4096)
            assert cobs_decode(c_bytes[:-1])[:4] == cobs_decode(python_bytes[:-1])[:4]
            assert cobs_decode(c_bytes[:-1])[4:7] == b"\x00\x01\x03"  # the bus's link sequence, continued
            h.state.fd_frames = 0
            out.fd, out.len = 1, 12
            assert lib.nl_serial_send(h.state, out) == -1 and host.stats.send_errors == 1
            h.state.fd_frames = 1
            h.release()
            assert bus.link_seq == (2, -1) and host.stats.frames_tx == 2
            one, two = _packet(0x181, b"\x11" * 8, 0), _packet(0x181, b"\x22" * 8, 1)
            a.sendall(one[:6])
            assert host.poll() is None  # half of it received by the bus
            h = WireHandle(SERIAL_WIRE, ffi, lib, bus, target_role=False)
            a.sendall(one[6:] + two[:6])
            f = ffi.new("hil_core_frame_t *")
            assert lib.nl_serial_recv(h.state, f, lib_deadline(1.0)) == 1 and bytes(f.data[0:8]) == b"\x11" * 8
            assert lib.nl_serial_recv(h.state, f, lib_deadline(0.05)) == 0  # the other half not here yet
            h.release()
            a.sendall(two[6:])
            fr = host.recv(1.0)
            assert fr is not None and fr.data == b"\x22" * 8 and host.stats.framing_errors == 0
            assert bus.link_seq == (2, 1) and host.stats.frames_rx == 2


def test_the_native_target_stops_when_the_host_closes_the_pty() -> None:
    master, slave = os.openpty()
    path = os.ttyname(slave)
    os.close(slave)
    proc = subprocess.Popen([sys.executable, "-m", "pmsm_hil.app.cli.main", "target", "--native", "--link",
                             f"serial:{path}", "--idle-timeout", "20"], stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None and proc.stdout.readline().startswith("ready serial:")
    finally:
        os.close(master)
    out, _ = proc.communicate(timeout=10)
    assert proc.returncode == 0 and "target stopped (link closed)" in out and "(native)" in out


def test_ctrl_c_ends_a_native_serial_run_safely() -> None:
    raised: list[int] = []

    def interrupt(periods: np.ndarray) -> None:
        if not raised:  # once, as a Ctrl-C while the blocks drain
            raised.append(periods.shape[0])
            raise KeyboardInterrupt

    cfg = _three(link="serial:pty", target="spawn", loop="native")
    res = run_closed_loop(replace(cfg, scenario=cfg.scenario.with_overrides(duration_s=0.3)), live=interrupt)
    assert res.metrics["loop"] == "native"
    assert res.metrics["end_code"] == 130 and res.metrics["end_reason"] == "interrupted (Ctrl-C or SIGTERM)"
    assert res.outcome.target_disabled and res.outcome.safe_state
    assert 1000 <= res.outcome.completed_periods < 3050
    assert res.metrics["link"]["lost"] == 0


def test_bench_loop_names_the_serial_pairs_as_the_udp_pairs(monkeypatch: pytest.MonkeyPatch) -> None:
    """`hil bench loop --cross-process udp,serial`: the same keys per link (the runs themselves faked here:
    the figures are in docs/benchmarks.md)."""
    from pmsm_hil.app.cli import bench_loop

    seen: list[tuple[str, str, str]] = []

    def fake_rate(make: Any, repeats: int, exclude_safe_stop: bool = False) -> dict[str, Any]:
        cfg = make()
        seen.append((cfg.link, cfg.target, cfg.loop))
        return {"periods_per_s": 1000.0 if cfg.loop == "native" else 500.0, "runs": [], "last_metrics": {}}

    monkeypatch.setattr(bench_loop, "_median_rate", fake_rate)
    monkeypatch.setattr(bench_loop, "_cpu_burner", contextlib.nullcontext)
    out = {}
    for name, spec in (("udp", "udp"), ("serial", "serial:pty")):
        out.update(bench_loop._native_pair_under_load(bench_loop._base(0.01), name, spec, 1, "1 × 0.01 s",
                                                      lambda _msg: None))
    for name in ("udp", "serial"):
        assert {k for k in out if k.startswith(f"lockstep_{name}_") or k.startswith(f"{name}_")} == {
            f"lockstep_{name}_native_hz", f"lockstep_{name}_python_hz", f"lockstep_{name}_native_loaded_hz",
            f"lockstep_{name}_python_loaded_hz", f"{name}_native_load_ratio", f"{name}_python_load_ratio"}
    assert ("serial:pty", "spawn", "native") in seen and ("serial:pty", "spawn", "python") in seen
