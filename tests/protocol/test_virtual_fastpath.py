"""The in-process virtual fast path stays interoperable with plain python-can virtual buses."""

from __future__ import annotations

import can

from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links import open_link


def test_fast_path_frames_reach_a_plain_python_can_bus_and_back() -> None:
    link = open_link("virtual:fastpath-test", "host")
    plain = can.Bus(interface="virtual", channel="fastpath-test", protocol=can.CanProtocol.CAN_FD)
    try:
        link.send([Frame(0x108, bytes(range(16)), True)])
        msg = plain.recv(1.0)
        assert msg is not None
        assert (msg.arbitration_id, bytes(msg.data), msg.is_fd, msg.is_rx) == (0x108, bytes(range(16)), True, True)
        plain.send(can.Message(arbitration_id=0x118, data=b"\x01\x02", is_extended_id=False))
        assert link.recv(1.0) == Frame(0x118, b"\x01\x02", False)
        assert link.poll() is None
        assert (link.stats.frames_tx, link.stats.frames_rx) == (1, 1)
    finally:
        plain.shutdown()
        link.close()
