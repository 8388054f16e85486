"""Kernel receive drops of SocketCAN links (src/pmsm_hil/protocol/links/socketcan_bus.py,
src/pmsm_hil/hil/runner/c/links/loop_socketcan.c): the receive buffer sized for `rx_frames`, and a burst that overflows
it counted in `kernel_dropped` by the Python link and by the C loop. The vcan tests run where vcan0 exists
(`.ci/vcan-vm`, docs/ci.md)."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest

from pmsm_hil.protocol.errors import LinkError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links import open_link
from pmsm_hil.protocol.links.kernel_drops import link_kernel_drops
from pmsm_hil.protocol.links.socketcan_bus import (
    RCVBUF_BYTES_PER_FRAME,
    SocketcanLinkBus,
    meminfo_drops,
    size_receive_buffer,
)

VCAN = Path("/sys/class/net/vcan0").exists()
needs_vcan = pytest.mark.skipif(not VCAN, reason="no SocketCAN interface vcan0 (kernel without vcan; "
                                "`ip link add vcan0 type vcan`; .ci/vcan-vm runs these)")
BURST = 1000


def test_receive_buffer_is_sized_for_the_frames_asked() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        granted = size_receive_buffer(s, 4096)
        assert granted >= min(4096 * RCVBUF_BYTES_PER_FRAME, int(Path("/proc/sys/net/core/rmem_max").read_text()))
        assert size_receive_buffer(s, 1) < granted
        assert meminfo_drops(s) == 0


def test_a_link_that_is_not_socketcan_reports_no_kernel_drops() -> None:
    with open_link("virtual:drops", "host") as link:
        assert link_kernel_drops(link) == {}


@needs_vcan
def test_a_bad_rx_frames_option_names_the_option() -> None:
    with pytest.raises(LinkError, match="rx_frames"):
        open_link("socketcan:vcan0,fd=true,rx_frames=lots", "host")


def _burst(frames: int) -> None:
    with open_link("socketcan:vcan0,fd=true", "target") as sender:
        sender.send([Frame(0x200, i.to_bytes(4, "little") + bytes(12), True) for i in range(frames)])


@needs_vcan
def test_a_burst_that_overflows_the_receive_buffer_is_counted_by_the_python_link() -> None:
    with open_link("socketcan:vcan0,fd=true,rx_frames=64", "host") as reader:
        assert isinstance(reader.bus, SocketcanLinkBus)
        _burst(BURST)  # the reader does not read meanwhile
        got = []
        while (fr := reader.poll()) is not None:
            got.append(int.from_bytes(fr.data[:4], "little"))
        dropped = link_kernel_drops(reader)["kernel_dropped"]  # the frames queued before the drops carry none
        assert 0 < len(got) < BURST and got == sorted(got)
        assert dropped == BURST - len(got), (len(got), dropped)
        _burst(1)  # the next frame queued carries the kernel's count (SO_RXQ_OVFL), read as it is received
        assert reader.poll() is not None and reader.bus._counting.dropped == dropped


@needs_vcan
def test_a_burst_that_overflows_the_receive_buffer_is_counted_by_the_c_loop() -> None:
    from pmsm_hil.hil._loop_native import ffi, lib

    from pmsm_hil.hil.runner.wire import WireHandle
    from pmsm_hil.hil.runner.wire_socketcan import SOCKETCAN_WIRE

    with open_link("socketcan:vcan0,fd=true,rx_frames=64", "host") as reader:
        h = WireHandle(SOCKETCAN_WIRE, ffi, lib, reader.bus, target_role=False, spin_ns=0)
        _burst(BURST)
        f = ffi.new("hil_core_frame_t *")
        received = 0
        while lib.nl_socketcan_recv(h.state, f, 0) == 1:
            received += 1
        assert 0 < received < BURST
        _burst(1)  # the next frame queued after the drops carries the kernel's count (SO_RXQ_OVFL)
        assert lib.nl_socketcan_recv(h.state, f, 0) == 1 and int(h.state.kernel_dropped) == BURST - received
        reader.bus._counting.dropped = 0  # what the C loop read reaches the bus
        h.release()
        assert reader.bus._counting.dropped == BURST - received
        assert link_kernel_drops(reader) == {"kernel_dropped": BURST - received}


@needs_vcan
def test_the_default_receive_buffer_holds_a_burst_of_a_runs_frames() -> None:
    with open_link("socketcan:vcan0,fd=true", "host") as reader:
        _burst(BURST)
        n = 0
        while reader.poll() is not None:
            n += 1
        assert (n, link_kernel_drops(reader)) == (BURST, {"kernel_dropped": 0})
