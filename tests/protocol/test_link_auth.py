"""Authenticated frames (firmware_stub/target/hil_auth.c; key options: src/pmsm_hil/protocol/links/auth.py): the C MAC
against Python's hmac/hashlib, C and the reference of docs/protocol.md (wire_oracle.py) seal and open each other's
frames, and the UDP and serial links (the C buses) drop (and count) spoofed, stripped and replayed frames."""

from __future__ import annotations

import binascii
import os
import socket
import time
from collections.abc import Iterator

import pytest

from pmsm_hil.hil.runner.core_link import native_lib
from pmsm_hil.protocol.errors import LinkError, LinkSpecError
from pmsm_hil.protocol.links import open_link
from pmsm_hil.protocol.links.auth import key_of_options, parse_key
from pmsm_hil.protocol.links.link import BusLink
from pmsm_hil.protocol.links.spec import parse_spec, redact_spec
from pmsm_hil.protocol.links.wire_bus import free_udp_ports
from tests.protocol.wire_oracle import (
    AUTH_FAILED,
    AUTH_OK,
    AUTH_REPLAYED,
    CRC_INIT,
    TRAILER,
    encode_packet,
    pack_frame,
)
from tests.protocol.wire_oracle import Sealer as FrameAuth

KEY = bytes(range(1, 33))
KEY_HEX = KEY.hex()


def test_the_c_hmac_sha256_is_pythons() -> None:
    import hashlib
    import hmac

    ffi, lib = native_lib()
    out = ffi.new("uint8_t[32]")
    for key_n in (16, 32, 63, 64):
        key = os.urandom(key_n)
        for n in (0, 1, 55, 56, 63, 64, 65, 119, 120, 200):  # around the padding and block edges
            msg = os.urandom(n)
            lib.hil_hmac_sha256(key, key_n, msg, n, out)
            assert bytes(out) == hmac.new(key, msg, hashlib.sha256).digest()


def _c_auth(ffi: object, lib: object, role: int, context: bytes = b"") -> object:
    a = ffi.new("hil_auth_t *")  # type: ignore[attr-defined]
    assert lib.hil_auth_init(a, KEY, len(KEY), role) == 0  # type: ignore[attr-defined]
    lib.hil_auth_set_context(a, context, len(context))  # type: ignore[attr-defined]
    return a


def test_c_and_python_open_each_others_frames_and_catch_alteration_and_replay() -> None:
    ffi, lib = native_lib()
    ctx = bytes.fromhex("0102030405060708")
    c_host = _c_auth(ffi, lib, 0, ctx)
    py_target = FrameAuth(KEY, "target")
    py_target.set_context(ctx)
    buf = ffi.new("uint8_t[96]")
    sealed: list[bytes] = []
    for i in range(70_000 // 500):  # jumps of 500 frames: the 16-bit freshness wraps on the way
        body = pack_frame(0x100 + i, bytes([i % 256]) * 8, 0, i)
        c_host.tx_fresh += 499  # type: ignore[attr-defined]
        ffi.memmove(buf, body, len(body))
        lib.hil_auth_seal(c_host, buf, len(body))
        frame = bytes(buf[0:len(body) + TRAILER])
        assert py_target.open(frame) == AUTH_OK
        sealed.append(frame)
    assert py_target.rx_fresh == 70_000 // 500 * 500 > 65_536
    assert py_target.open(sealed[-1]) == AUTH_REPLAYED and py_target.open(sealed[-2]) == AUTH_REPLAYED
    altered = bytearray(sealed[-1])
    altered[8] ^= 1
    assert py_target.open(bytes(altered)) == AUTH_FAILED
    # a frame reflected back to its sender (the other direction) fails
    assert FrameAuth(KEY, "host").open(sealed[0]) == AUTH_FAILED
    # Python seals, C opens; a replay and a frame of another context fail there too
    py_host, c_target = FrameAuth(KEY, "host"), _c_auth(ffi, lib, 1, ctx)
    py_host.set_context(ctx)
    frames = [py_host.seal(pack_frame(0x110, bytes(20), 1, k)) for k in range(3)]
    assert [lib.hil_auth_open(c_target, f, len(f)) for f in frames] == [1, 1, 1]
    assert lib.hil_auth_open(c_target, frames[1], len(frames[1])) == -1
    other = FrameAuth(KEY, "host")
    other.set_context(b"\0" * 8)
    f = other.seal(pack_frame(0x110, bytes(20), 1, 9))
    assert lib.hil_auth_open(c_target, f, len(f)) == 0


def test_keys_and_link_options_are_checked_and_never_shown() -> None:
    assert parse_key(KEY_HEX) == KEY
    for bad, why in (("xyz", "not hexadecimal"), ("00" * 15, "15 bytes"), ("00" * 65, "65 bytes")):
        with pytest.raises(LinkSpecError, match=why):
            parse_key(bad, "link option key")
    # a key of digits only keeps its leading zeros (never read as a number)
    assert parse_spec("udp:1:2,key=" + "0" * 32).options["key"] == "0" * 32
    with pytest.raises(LinkSpecError, match="auth=on needs key"):
        key_of_options({"auth": "on"})
    with pytest.raises(LinkSpecError, match="give one"):
        key_of_options({"key": KEY_HEX, "keyfile": "/x"})
    with pytest.raises(LinkSpecError, match="keyfile /nonexistent/k: cannot read"):
        key_of_options({"keyfile": "/nonexistent/k"})
    assert redact_spec(f"udp:1:2,fd=true,key={KEY_HEX}") == "udp:1:2,fd=true,key=***"
    with pytest.raises(LinkError) as err:
        open_link(f"udp:1:0,key={KEY_HEX}", "host")
    assert KEY_HEX not in str(err.value)


@pytest.fixture
def udp_pair() -> Iterator[tuple[BusLink, BusLink, int, int]]:
    a, b = free_udp_ports()
    host = open_link(f"udp:{a}:{b},key={KEY_HEX}", "host")
    target = open_link(f"udp:{b}:{a},key={KEY_HEX}", "target")
    try:
        _agree(host, target)
        yield host, target, a, b
    finally:
        host.close()
        target.close()


def _agree(host: BusLink, target: BusLink) -> None:
    host.bus.propose()  # type: ignore[attr-defined]
    deadline = time.monotonic() + 5
    while not (host.bus.established and target.bus.established):  # type: ignore[attr-defined]
        assert time.monotonic() < deadline, "no session agreed"
        host.bus.poll_frame()  # type: ignore[attr-defined]
        target.bus.poll_frame()  # type: ignore[attr-defined]
        time.sleep(0.001)


def _receive(link: BusLink, timeout_s: float = 0.5) -> list[tuple[int, bytes]]:
    got, deadline = [], time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        f = link.bus.poll_frame()  # type: ignore[attr-defined]
        if f is not None:
            got.append((f.arbitration_id, f.data))
        else:
            time.sleep(0.002)
    return got


def test_udp_spoofed_stripped_and_replayed_datagrams_from_the_peers_port_are_dropped_and_counted(
        udp_pair: tuple[BusLink, BusLink, int, int]) -> None:
    host, target, a, b = udp_pair
    session = host.bus.session.to_bytes(4, "little")  # type: ignore[attr-defined]
    # capture a genuine datagram on its way to the host (read off the host's socket), then hand it over
    target.bus.send_frame(0x118, b"genuine!", False)  # type: ignore[attr-defined]
    time.sleep(0.05)
    genuine = os.read(host.bus.fileno(), 2048)  # type: ignore[attr-defined]
    target.close()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as spoofer:  # another socket on the peer's port
        spoofer.bind(("127.0.0.1", b))
        spoofer.connect(("127.0.0.1", a))
        spoofer.send(genuine)  # delivered once
        spoofer.send(genuine)  # a replay
        forged = bytearray(genuine)
        forged[4 + 7] ^= 0xFF  # another payload byte, the CRC fixed: the MAC no longer matches
        crc = binascii.crc_hqx(bytes(forged[4:-2]), CRC_INIT)
        spoofer.send(bytes(forged[:-2]) + crc.to_bytes(2, "big"))
        plain = pack_frame(0x118, b"spoofed!", 0, 77)  # right session and CRC, no trailer at all
        spoofer.send(session + plain + binascii.crc_hqx(plain, CRC_INIT).to_bytes(2, "big"))
        sealed_by_stranger = FrameAuth(os.urandom(32), "target")  # right layout, a wrong key
        sealed_by_stranger.set_context(session + host.bus.nonce.to_bytes(4, "little"))  # type: ignore[attr-defined]
        body = sealed_by_stranger.seal(pack_frame(0x118, b"spoofed!", 0, 78))
        spoofer.send(session + body + binascii.crc_hqx(body, CRC_INIT).to_bytes(2, "big"))
        assert _receive(host) == [(0x118, b"genuine!")]
    stats = host.stats
    assert stats.auth_replayed == 1 and stats.auth_failed == 3 and stats.frames_rx == 1
    assert stats.crc_errors == stats.framing_errors == 0


def test_udp_a_wrong_key_or_a_missing_one_is_a_clear_error_at_the_handshake() -> None:
    for host_opt, target_opt, want in (
            (f",key={KEY_HEX}", f",key={'ab' * 32}", "its authentication key differs"),
            ("", f",key={KEY_HEX}", "authenticates frames and this end does not"),
            (f",key={KEY_HEX}", "", "does not authenticate frames and this end does")):
        a, b = free_udp_ports()
        host = open_link(f"udp:{a}:{b}{host_opt}", "host")
        target = open_link(f"udp:{b}:{a}{target_opt}", "target")
        try:
            host.bus.propose()  # type: ignore[attr-defined]
            for _ in range(50):
                target.bus.poll_frame()  # type: ignore[attr-defined]
                time.sleep(0.002)
            with pytest.raises(LinkError, match=want):
                host.bus.wait_session(2.0)  # type: ignore[attr-defined]
            assert target.stats.auth_failed >= 1 and not target.bus.established  # type: ignore[attr-defined]
        finally:
            host.close()
            target.close()


def test_serial_over_a_pty_authenticates_and_drops_spoofed_and_replayed_packets() -> None:
    master, slave = os.openpty()
    host = open_link(f"serial:fd:{master},key={KEY_HEX}", "host")
    target = open_link(f"serial:{os.ttyname(slave)},key={KEY_HEX}", "target")
    try:
        host.bus.send_frame(0x200, b"\x01\x02", False)  # type: ignore[attr-defined]
        assert _receive(target, 0.2) == [(0x200, b"\x01\x02")]
        target.bus.send_frame(0x211, b"ok", False)  # type: ignore[attr-defined]
        # capture the target's packet off the line, then replay it, forge one and strip one (as a writer on the tty)
        time.sleep(0.05)
        genuine = os.read(master, 4096)
        assert genuine.endswith(b"\0")
        os.write(slave, genuine)  # the genuine one reaches the host (written back by the capturer)
        assert _receive(host, 0.2) == [(0x211, b"ok")]
        os.write(slave, genuine)  # a replay
        os.write(slave, encode_packet(pack_frame(0x211, b"spoofed!", 0, 5)))  # no trailer
        forged = FrameAuth(os.urandom(16), "target").seal(pack_frame(0x211, b"no", 0, 6))  # a wrong key
        os.write(slave, encode_packet(forged))
        assert _receive(host, 0.2) == []
        assert host.stats.auth_replayed == 1 and host.stats.auth_failed == 2 and host.stats.crc_errors == 0
    finally:
        host.close()
        target.close()
        os.close(slave)
