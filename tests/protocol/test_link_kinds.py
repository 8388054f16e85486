"""The link-kind registry: profile, wire budget, spawn mirroring and auto-target rule kept once per kind."""

from __future__ import annotations

import os
from collections.abc import Iterator

import can
import pytest

from pmsm_hil.protocol.errors import LinkSpecError
from pmsm_hil.protocol.frame import Frame
from pmsm_hil.protocol.links import LINK_KINDS, LinkKind, link_kind, link_profile, open_link, parse_spec
from pmsm_hil.protocol.links.kinds import PYTHON_CAN_ADAPTER, register_link_kind


@pytest.mark.parametrize(("spec", "profile"), [
    ("virtual", "canfd"), ("virtual,fd=false", "can"), ("udp:1:2", "canfd"), ("serial:/dev/ttyACM0", "canfd"),
    ("socketcan:can0", "can"), ("socketcan:can0,fd=true", "canfd"), ("pcan:PCAN_USBBUS1", "can"), ("can", "can"),
])
def test_frame_profile_by_kind(spec: str, profile: str) -> None:
    assert link_profile(spec) == profile


def test_fd_option_must_be_a_boolean() -> None:
    with pytest.raises(LinkSpecError, match="fd must be true or false"):
        link_profile("socketcan:can0,fd=maybe")


def test_wire_budget_by_kind() -> None:
    for spec in ("virtual", "udp:1:2", "hiludp:1:2"):
        ls = parse_spec(spec)
        assert link_kind(ls).budget(ls, 10_000.0, 3) is None
    serial = parse_spec("serial:/dev/ttyUSB0,baudrate=3000000")
    assert link_kind(serial).budget(serial, 1000.0, 3).max_rate_hz == pytest.approx(5172.4, abs=0.1)
    can_spec = parse_spec("kvaser:0,bitrate=1000000")
    assert link_kind(can_spec) is PYTHON_CAN_ADAPTER
    six = link_kind(can_spec).budget(can_spec, 1000.0, 6)
    three = link_kind(can_spec).budget(can_spec, 1000.0, 3)
    assert six is not None and three is not None and six.max_rate_hz < three.max_rate_hz


def test_spawn_mirroring() -> None:
    udp = parse_spec("udp:5000:5001@127.0.0.1,fd=true")
    specs = link_kind(udp).mirror("udp:5000:5001@127.0.0.1,fd=true", udp)
    assert (specs.host, specs.target, specs.keep_open) == ("udp:5000:5001@127.0.0.1,fd=true",
                                                           "udp:5001:5000@127.0.0.1,fd=true", [])
    pty = parse_spec("serial:pty,baudrate=3000000")
    specs = link_kind(pty).mirror("serial:pty,baudrate=3000000", pty)
    try:
        assert specs.host.startswith("serial:fd:") and specs.target.startswith("serial:/dev/pts/")
        assert specs.target.endswith(",baudrate=3000000") and len(specs.keep_open) == 1
    finally:
        os.close(specs.keep_open[0])
        os.close(int(specs.host.split(":")[2].split(",")[0]))


@pytest.mark.parametrize(("spec", "target"), [("virtual", "inproc"), ("serial:pty", "spawn"),
                                              ("serial:/dev/ttyACM0", "external"), ("udp:1:2", "external"),
                                              ("socketcan:can0", "external")])
def test_auto_target_rule(spec: str, target: str) -> None:
    ls = parse_spec(spec)
    assert link_kind(ls).auto_target(ls) == target


@pytest.fixture
def loop_kind() -> Iterator[str]:
    """A new kind registered with one entry (python-can's virtual bus under another name)."""
    def open_loop(ls: object, role: str) -> tuple[can.BusABC, str]:
        return can.Bus(interface="virtual", channel="loop-kind", receive_own_messages=False), "loop"

    register_link_kind(LinkKind("loopkind", "loopkind a test kind", open_loop, fd_default=False, wire="none"))
    yield "loopkind"
    del LINK_KINDS["loopkind"]


def test_a_registered_kind_opens_and_carries_frames(loop_kind: str) -> None:
    assert link_profile(loop_kind) == "can"
    with open_link(loop_kind, "host") as host, open_link(loop_kind, "target") as target:
        host.send([Frame(0x100, b"\x01\x02", False)])
        got = target.recv(1.0)
        assert got is not None and got.data == b"\x01\x02"
