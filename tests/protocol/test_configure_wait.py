"""`TargetClient.configure` on a link of its own (UDP here) waits for the ConfigAcks in the link's receive, not by
polling it: a board that stopped answering is given its whole timeout without the host spinning on a core (the
labgrid bench's dead board: 10 s of a core), and a target that answers late is still configured."""

from __future__ import annotations

import threading
import time
from collections.abc import Iterator

import pytest

from pmsm_hil.hil.runner.target_client import DutViolationError, TargetClient
from pmsm_hil.protocol.codec import FrameCodec
from pmsm_hil.protocol.ids import ParamId, Status
from pmsm_hil.protocol.links import open_link
from pmsm_hil.protocol.links.link import BusLink
from pmsm_hil.protocol.links.wire_bus import free_udp_ports
from pmsm_hil.protocol.messages import ConfigAck, ConfigParam
from tests.protocol.test_link_auth import _agree

PARAMS = {ParamId.RS: 0.5, ParamId.LD: 1e-4}


@pytest.fixture
def udp_pair() -> Iterator[tuple[BusLink, BusLink]]:
    """A host and a target end on loopback with their session agreed."""
    a, b = free_udp_ports()
    host, target = open_link(f"udp:{a}:{b}", "host"), open_link(f"udp:{b}:{a}", "target")
    try:
        _agree(host, target)
        yield host, target
    finally:
        host.close()
        target.close()


def test_a_silent_target_is_waited_for_without_spinning(udp_pair: tuple[BusLink, BusLink]) -> None:
    host, target = udp_pair
    target.close()  # the board stopped answering after the session was agreed
    client = TargetClient(host, FrameCodec("canfd"))
    wall0, cpu0 = time.monotonic(), time.thread_time()
    with pytest.raises(DutViolationError, match="did not acknowledge parameter"):
        client.configure(PARAMS, timeout_s=1.0, resend_s=0.25)
    wall, cpu = time.monotonic() - wall0, time.thread_time() - cpu0
    assert wall >= 1.0  # polling, the host took 0.2–0.33 CPU-s of this second at load 9.5
    assert cpu < 0.05 * wall, f"the host spun: {cpu:.3f} CPU-s in {wall:.3f} s of waiting"
    assert client.config_resent >= 2 * len(PARAMS)  # still resent every resend_s while it waited


def test_a_target_that_answers_late_is_configured(udp_pair: tuple[BusLink, BusLink]) -> None:
    host, target = udp_pair
    codec = FrameCodec("canfd")

    def late_target() -> None:  # acknowledges only what it receives 0.4 s after the first ConfigParam
        decoder, first, acked = codec.decoder(ordered=False), None, set()
        end = time.monotonic() + 30
        while len(acked) < len(PARAMS) and time.monotonic() < end:
            frame = target.recv(0.05)
            msg = decoder.feed(frame) if frame is not None else None
            if isinstance(msg, ConfigParam):
                first = time.monotonic() if first is None else first
                if time.monotonic() - first >= 0.4:
                    target.send(codec.encode(ConfigAck(param_id=msg.param_id, value=msg.value,
                                                       status=int(Status.OK))))
                    acked.add(msg.param_id)

    thread = threading.Thread(target=late_target)
    thread.start()
    try:
        client = TargetClient(host, codec)
        wall0, cpu0 = time.monotonic(), time.thread_time()
        client.configure(PARAMS, timeout_s=20.0, resend_s=0.1)
        wall, cpu = time.monotonic() - wall0, time.thread_time() - cpu0
    finally:
        thread.join()
    assert set(client._acks) == {int(p) for p in PARAMS}
    assert wall >= 0.4 and client.config_resent >= len(PARAMS)
    assert cpu < 0.05 * wall, f"the host spun: {cpu:.3f} CPU-s in {wall:.3f} s of waiting"
