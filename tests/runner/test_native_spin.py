"""The adaptive spin of the native links (hil/native/nl_link.c): spin while it pays, block at once when the
spins keep running out (the peer shares a core with other work), then try spinning again."""

from __future__ import annotations

import socket
import time
from collections.abc import Iterator

import pytest
from pmsm_hil.hil.runner.native_link import native_lib

WINDOW, BACKOFF = 256, 4096


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


def test_spins_that_keep_running_out_switch_to_blocking_then_spinning_is_tried_again(pair) -> None:
    ffi, lib = native_lib()
    a, _ = pair
    spin, stats = ffi.new("nl_spin_t *"), ffi.new("nl_link_stats_t *")
    spin.spin_ns = 5_000
    for _ in range(2 * WINDOW - 1):  # nothing ever comes: each spin runs out, then ppoll to the deadline
        _receive(lib, ffi, a.fileno(), spin, stats, 200_000)
    assert spin.backoffs == 0  # two full contended windows are needed
    _receive(lib, ffi, a.fileno(), spin, stats, 200_000)
    assert spin.backoffs == 1 and spin.block_left == BACKOFF
    blocked = stats.blocked
    calls = _receive(lib, ffi, a.fileno(), spin, stats, 200_000)
    assert stats.blocked == blocked + 1 and calls <= 2  # blocked at once: no spinning polls
    assert spin.block_left == BACKOFF - 1
    spin.block_left = 1  # the last blocking receive, then a spin again
    _receive(lib, ffi, a.fileno(), spin, stats, 200_000)
    assert spin.block_left == 0
    calls = _receive(lib, ffi, a.fileno(), spin, stats, 200_000)
    assert calls > 2  # spinning polls before the block


def test_spins_that_find_the_frame_keep_spinning(pair) -> None:
    ffi, lib = native_lib()
    a, b = pair
    spin, stats = ffi.new("nl_spin_t *"), ffi.new("nl_link_stats_t *")
    spin.spin_ns = 50_000
    spun_out = 0
    for _ in range(3 * WINDOW):
        b.send(b"x")  # the frame is there while the receive spins
        spin_end = ffi.new("int64_t *", -1)
        assert lib.nl_wait_readable(a.fileno(), time.monotonic_ns() + 1_000_000, spin, spin_end, stats) == 1
        a.recv(1)
        spun_out = max(spun_out, spin.window_spun_out)
    assert spun_out == 0  # no spin ran out (a loaded machine may still make the thread wait: the other rule)
    if spin.backoffs == 0:
        assert spin.block_left == 0 and stats.blocked == 0
