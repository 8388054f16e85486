"""The adaptive spin of the native links (src/pmsm_hil/hil/runner/c/links/nl_link.c): spin while it pays, block at once
when the spins keep running out (the peer shares a core with other work) - longer each time the load stays - then try
spinning again; a peer with nothing to send is no load."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import time
from collections.abc import Iterator

import pytest

from pmsm_hil.hil.runner.core_link import native_lib


@pytest.fixture
def pair() -> Iterator[tuple[socket.socket, socket.socket]]:
    a, b = socket.socketpair()
    yield a, b
    a.close()
    b.close()


def _receive(lib: object, ffi: object, fd: int, spin: object, stats: object, wait_ns: int) -> int:
    """One receive as the links do it: wait until readable or the deadline; the number of waits it took."""
    spin_end = ffi.new("int64_t *", -1)  # type: ignore[attr-defined]
    deadline = time.monotonic_ns() + wait_ns  # CLOCK_MONOTONIC, as the C side
    calls = 0
    while lib.nl_wait_readable(fd, deadline, spin, spin_end, stats) == 1:  # type: ignore[attr-defined]
        calls += 1
    return calls


def _until_backoff(lib: object, ffi: object, fd: int, spin: object, stats: object) -> int:
    """Receives that never get a frame (each spin runs out, then ppoll to a near deadline) until the next
    back-off; how many. (A receive whose deadline passed before C saw it - Python descheduled for 200 µs -
    is no receive that waited: counting to the back-off instead of a fixed number keeps that out of the test.)"""
    before, n = spin.backoffs, 0  # type: ignore[attr-defined]
    while spin.backoffs == before:  # type: ignore[attr-defined]
        _receive(lib, ffi, fd, spin, stats, 200_000)
        n += 1
        assert n < 8 * lib.NL_SPIN_WINDOW, "no back-off although every spin ran out"  # type: ignore[attr-defined]
    return n


def test_spins_that_keep_running_out_switch_to_blocking_longer_each_time(pair) -> None:
    ffi, lib = native_lib()
    a, _ = pair
    window, backoff = lib.NL_SPIN_WINDOW, lib.NL_SPIN_BACKOFF
    spin, stats = ffi.new("nl_spin_t *"), ffi.new("nl_link_stats_t *")
    spin.spin_ns = 5_000
    blocked = stats.blocked
    assert _until_backoff(lib, ffi, a.fileno(), spin, stats) >= 2 * window  # two full contended windows
    assert spin.backoffs == 1 and spin.block_left == backoff - 1  # the last receive already blocked at once
    assert spin.rx_backed_off == 1 and stats.blocked > blocked
    assert spin.spin_wait_ns >= 150_000  # the window's receives waited ~200 µs each
    spin.spin_wait_ns = 10**9  # (the back-off check is the next test: here blocking always pays)
    _receive(lib, ffi, a.fileno(), spin, stats, 200_000)
    assert spin.rx_backed_off == 1 and spin.block_left <= backoff - 2
    spin.block_left = 1  # the last blocking receive, then a spin again
    _receive(lib, ffi, a.fileno(), spin, stats, 200_000)
    assert spin.block_left == 0
    _receive(lib, ffi, a.fileno(), spin, stats, 200_000)
    assert spin.rx_backed_off == 0 and spin.window_n == 1  # a spinning receive, the first of a new window
    _until_backoff(lib, ffi, a.fileno(), spin, stats)  # still contended: the next back-off is longer
    assert spin.backoffs == 2 and spin.block_left == 2 * backoff - 1
    spin.block_left, spin.doublings = 0, lib.NL_SPIN_BACKOFF_DOUBLINGS
    _until_backoff(lib, ffi, a.fileno(), spin, stats)
    assert spin.backoffs == 3 and spin.block_left == (backoff << lib.NL_SPIN_BACKOFF_DOUBLINGS) - 1  # capped
    assert spin.doublings == lib.NL_SPIN_BACKOFF_DOUBLINGS


def _backed_off(lib: object, ffi: object, spin_wait_ns: int) -> tuple[object, object]:
    spin, stats = ffi.new("nl_spin_t *"), ffi.new("nl_link_stats_t *")  # type: ignore[attr-defined]
    spin.spin_ns, spin.block_left, spin.doublings = 5_000, lib.NL_SPIN_BACKOFF, 2  # type: ignore[attr-defined]
    spin.spin_wait_ns = spin_wait_ns  # mean wait of a receive in the spinning window that started the back-off
    return spin, stats


def test_a_backoff_ends_early_when_blocking_waits_longer_than_spinning_did(pair) -> None:
    """The load went away (or was never there): a blocked receive waits for an idle CPU to wake - here ~200 µs
    against the 20 µs the spinning receives waited - so spinning comes back after one check, not 4096 receives."""
    ffi, lib = native_lib()
    a, _ = pair
    spin, stats = _backed_off(lib, ffi, 20_000)
    n = 0
    while True:
        _receive(lib, ffi, a.fileno(), spin, stats, 200_000)
        if spin.rx_backed_off == 0:
            break
        n += 1
        assert n <= lib.NL_SPIN_CHECK + 2, "the back-off did not end after one check"
    assert n >= lib.NL_SPIN_CHECK - 2  # one check's worth blocked at once first
    assert spin.block_left == 0 and spin.window_n == 1  # spinning again
    assert spin.early_ends == 1 and spin.doublings == 0  # the next back-off is the shortest


def test_a_backoff_that_pays_runs_its_length(pair) -> None:
    """Blocking waits less than the spinning it replaced (a CPU burner made each spin ~20 ms): it stays. (Each
    blocked receive here waits its 200 µs deadline and a wake-up: at load 20 that passed 1 ms.)"""
    ffi, lib = native_lib()
    a, _ = pair
    spin, stats = _backed_off(lib, ffi, 20_000_000)
    for _ in range(3 * lib.NL_SPIN_CHECK + 1):
        _receive(lib, ffi, a.fileno(), spin, stats, 200_000)
        assert spin.rx_backed_off == 1
    assert spin.early_ends == 0 and 0 < spin.block_left <= lib.NL_SPIN_BACKOFF - 2 * lib.NL_SPIN_CHECK


def test_a_peer_with_nothing_to_send_is_no_load(pair) -> None:
    """Spins that run out long before the frame comes (a host between runs, Python sending a Setpoint) are not
    counted: blocking then costs nothing, and they say nothing about the CPU."""
    ffi, lib = native_lib()
    a, _ = pair
    spin, stats = ffi.new("nl_spin_t *"), ffi.new("nl_link_stats_t *")
    spin.spin_ns = 5_000
    for _ in range(2 * lib.NL_SPIN_WINDOW + 8):
        _receive(lib, ffi, a.fileno(), spin, stats, lib.NL_SPIN_NEAR_MISS_NS + 500_000)
    assert spin.window_spun_out == 0 and spin.backoffs == 0


@pytest.mark.timing  # 1 ms receive deadlines: a thread preempted mid-spin on a busy machine runs its spin out
def test_spins_that_find_the_frame_keep_spinning_and_a_clean_window_resets_the_backoff(pair) -> None:
    ffi, lib = native_lib()
    a, b = pair
    spin, stats = ffi.new("nl_spin_t *"), ffi.new("nl_link_stats_t *")
    spin.spin_ns = 50_000
    spin.doublings = 3  # left from earlier back-offs
    spun_out = 0
    for _ in range(3 * lib.NL_SPIN_WINDOW):
        b.send(b"x")  # the frame is there while the receive spins
        spin_end = ffi.new("int64_t *", -1)
        assert lib.nl_wait_readable(a.fileno(), time.monotonic_ns() + 1_000_000, spin, spin_end, stats) == 1
        a.recv(1)
        spun_out = max(spun_out, spin.window_spun_out)
    assert spun_out == 0  # no spin ran out (a loaded machine may still make the thread wait: the other rule)
    if spin.backoffs == 0:  # a window was clean
        assert spin.block_left == 0 and stats.blocked == 0 and spin.doublings == 0


def test_a_process_on_one_cpu_does_not_spin(monkeypatch: pytest.MonkeyPatch) -> None:
    from pmsm_hil.hil.runner import wire
    monkeypatch.setattr(wire.os, "sched_getaffinity", lambda _pid: {1})
    assert wire.default_spin_ns() == 0  # a spin would only delay the peer it waits for
    monkeypatch.setattr(wire.os, "sched_getaffinity", lambda _pid: {0, 1})
    assert wire.default_spin_ns() == wire.SPIN_NS > 0


def test_the_udp_floor_is_a_real_round_trip_between_two_processes() -> None:
    """src/pmsm_hil/hil/runner/c/links/link_floor.c (`hil bench loop` prints it beside the native pair): every round
    trip is timed, a blocking one costs at least a wake-up of the other process, nothing is left running."""
    ffi, lib = native_lib()
    out = ffi.new("nl_udp_floor_t *")
    for spin_ns in (50_000, 0):
        assert lib.nl_udp_floor(300, spin_ns, out) == 0
        assert out.round_trips == 300 and 0 < out.mean_ns <= out.max_ns
        assert out.mean_ns >= 1_000  # two system calls each way and a context switch or a cross-CPU hand-off


#: `nl_udp_paced_floor` in a small process: it locks the calling process's memory (mlockall), which in a pytest
#: worker (gigabytes mapped, pages shared with the forked echo) costs seconds of system time per call; the floor's
#: pacing and counting are the same in any process
_PACED_FLOOR = """
import json, sys
from pmsm_hil.hil.runner.core_link import native_lib
ffi, lib = native_lib()
out = ffi.new("nl_udp_paced_floor_t *")
rows = []
for n, period_ns, spin_ns in json.loads(sys.argv[1]):
    rc = lib.nl_udp_paced_floor(n, period_ns, -1, 0, spin_ns, out)
    rows.append([rc, out.periods, out.late, out.median_ns, out.max_ns])
print(json.dumps(rows))
"""


def _paced_floors(*calls: tuple[int, int, int]) -> list[list[int]]:
    """(rc, periods, late, median_ns, max_ns) of `nl_udp_paced_floor(n, period_ns, spin_ns)` per call."""
    proc = subprocess.run([sys.executable, "-c", _PACED_FLOOR, json.dumps(calls)], capture_output=True, text=True,
                          timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    rows: list[list[int]] = json.loads(proc.stdout)
    return rows


def test_the_paced_udp_floor_paces_every_period_and_counts_late_replies() -> None:
    """`nl_udp_paced_floor` (the floor under `hil bench realtime`'s UDP misses): one datagram per period, each
    reply timed; at 1 µs (shorter than two system calls) nearly all are late — and the schedule goes on after each
    late one. (None late at a long period holds on an idle machine only: the `timing` test below.)"""
    # the echo spinning as the target on three CPUs, blocking as on fewer; then a period shorter than a round trip
    spinning, blocking, short = _paced_floors((20, 2_000_000, 50_000), (20, 2_000_000, 0), (200, 1_000, 0))
    for rc, periods, late, median_ns, max_ns in (spinning, blocking):
        assert rc == 0 and periods == 20 and 0 <= late <= 20 and 0 < median_ns <= max_ns + 1_000
    rc, periods, late, median_ns, _ = short
    assert rc == 0 and periods == 200 and late >= 150 and median_ns >= 1_000


@pytest.mark.timing  # a 20 ms period with no late reply: a busy machine leaves the echo unscheduled that long
def test_the_paced_udp_floor_has_no_late_reply_at_a_long_period() -> None:
    ffi, lib = native_lib()
    out = ffi.new("nl_udp_paced_floor_t *")
    for spin_ns in (50_000, 0):
        assert lib.nl_udp_paced_floor(20, 20_000_000, -1, 0, spin_ns, out) == 0
        assert out.periods == 20 and out.late == 0


def test_bench_loop_prints_the_udp_floor_and_its_load_ratio(monkeypatch: pytest.MonkeyPatch) -> None:
    import contextlib

    from pmsm_hil.app.cli import bench_loop
    monkeypatch.setattr(bench_loop, "_cpu_burner", contextlib.nullcontext)  # the figure itself: docs/benchmarks.md
    out = bench_loop._udp_floor(lambda _msg: None, round_trips=200)
    assert set(out) == {"udp_floor_spin_us", "udp_floor_block_us", "udp_floor_spin_loaded_us",
                        "udp_floor_block_loaded_us", "udp_floor_load_ratio"}
    best_idle = min(out["udp_floor_spin_us"], out["udp_floor_block_us"])
    best_loaded = min(out["udp_floor_spin_loaded_us"], out["udp_floor_block_loaded_us"])
    assert out["udp_floor_load_ratio"] == pytest.approx(best_idle / best_loaded)
