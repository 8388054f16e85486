"""Authenticated frames on the UDP and serial links, in the spirit of AUTOSAR SecOC (docs/protocol.md,
"Authenticated frames"; firmware_stub/target/hil_auth.c is the same in C).

Every frame body (header + payload) is followed by a 6-byte trailer: the low 16 bits of the sender's freshness
counter (u16 LE) and a MAC truncated to 32 bits, the first 4 bytes of
HMAC-SHA256(key, direction || context || freshness u64 LE || header || payload). `direction` is the sender's
role (b"H" host, b"T" target: a frame reflected back to its sender fails), `context` the UDP session id and the
adopting end's nonce (empty on serial). Each direction counts from 1 (again when a UDP session is agreed); the
receiver reads the 16 wire bits as the nearest value at most 32767 ahead of the last frame it accepted. A frame
whose MAC fails is dropped and counted in `auth_failed`; one whose MAC holds but whose freshness is not ahead is a
replay, dropped and counted in `auth_replayed`.

Keys: 16-64 bytes, given as hex (`key=HEX` in a link SPEC, or `keyfile=PATH` naming a file holding the hex); a
spawned target gets a fresh random key per run from its host over its stdin (never on a command line).
"""

from __future__ import annotations

import hmac
import secrets
import struct
from pathlib import Path
from typing import Any, Literal

from pmsm_hil.protocol.errors import LinkSpecError

KEY_MIN, KEY_MAX = 16, 64
FRESH_SIZE = 2
MAC_SIZE = 4
#: bytes the authentication adds to every frame (freshness low bits + truncated MAC)
TRAILER = FRESH_SIZE + MAC_SIZE
DIR_HOST, DIR_TARGET = b"H", b"T"
#: prefixed to the direction of a UDP control datagram's MAC
DIR_CONTROL = b"C"
#: the spawned-target key length [bytes]
SPAWN_KEY_BYTES = 32
_FRESH = struct.Struct("<Q")
_LOW = struct.Struct("<H")
AUTH_OK, AUTH_FAILED, AUTH_REPLAYED = 1, 0, -1


def parse_key(text: str, source: str = "key") -> bytes:
    """A key from hex text (whitespace ignored); LinkSpecError naming `source` when not 16-64 bytes of hex."""
    hexdigits = "".join(str(text).split())
    try:
        key = bytes.fromhex(hexdigits)
    except ValueError:
        raise LinkSpecError(f"{source}: not hexadecimal (expected {2 * KEY_MIN}-{2 * KEY_MAX} hex digits)") from None
    if not KEY_MIN <= len(key) <= KEY_MAX:
        raise LinkSpecError(f"{source}: {len(key)} bytes, a key has {KEY_MIN}-{KEY_MAX} bytes "
                            f"({2 * KEY_MIN}-{2 * KEY_MAX} hex digits)")
    return key


def read_key_file(path: str) -> bytes:
    """The hex key in file `path` (LinkSpecError naming the file when unreadable or not a key)."""
    try:
        text = Path(path).expanduser().read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise LinkSpecError(f"keyfile {path}: cannot read: {exc}") from None
    return parse_key(text, f"keyfile {path}")


def new_key() -> bytes:
    """A fresh random key for one spawned target."""
    return secrets.token_bytes(SPAWN_KEY_BYTES)


def key_of_options(options: dict[str, Any]) -> bytes | None:
    """Pop `key`, `keyfile` and `auth` of link SPEC options: the key they give, None for none. `auth=off` is
    taken here (no key); `auth=on` without a key is an error (only a spawned target gets one made)."""
    key_text, key_file, auth = options.pop("key", None), options.pop("keyfile", None), options.pop("auth", None)
    if key_text is not None and key_file is not None:
        raise LinkSpecError("link options key and keyfile: give one")
    if auth is not None and str(auth).lower() not in ("on", "off", "true", "false"):
        raise LinkSpecError(f"link option auth must be on or off, got {auth!r}")
    if str(auth).lower() in ("off", "false"):
        if key_text is not None or key_file is not None:
            raise LinkSpecError("link option auth=off with a key: give one or the other")
        return None
    if key_text is not None:
        return parse_key(str(key_text), "link option key")
    if key_file is not None:
        return read_key_file(str(key_file))
    if auth is not None:
        raise LinkSpecError("link option auth=on needs key=HEX or keyfile=PATH (spawned targets get a key made)")
    return None


class FrameAuth:
    """One link end's authentication state: its key, role, context and both freshness counters."""

    __slots__ = ("_key", "context", "rx_dir", "rx_fresh", "tx_dir", "tx_fresh")

    def __init__(self, key: bytes, role: Literal["host", "target"]) -> None:
        if not KEY_MIN <= len(key) <= KEY_MAX:
            raise LinkSpecError(f"authentication key: {len(key)} bytes, a key has {KEY_MIN}-{KEY_MAX} bytes")
        self._key = bytes(key)
        self.tx_dir, self.rx_dir = (DIR_TARGET, DIR_HOST) if role == "target" else (DIR_HOST, DIR_TARGET)
        self.context = b""
        self.tx_fresh = 0  #: freshness of the last frame sent
        self.rx_fresh = 0  #: freshness of the last frame accepted (0: none yet)

    @property
    def key(self) -> bytes:
        """The key (handed to a native loop taking the link over)."""
        return self._key

    def set_context(self, context: bytes) -> None:
        """MAC context from now on (UDP: session id + nonce); both freshness counters start again."""
        self.context = bytes(context)
        self.tx_fresh = self.rx_fresh = 0

    def mac(self, direction: bytes, fresh: int, body: bytes) -> bytes:
        """The truncated MAC of a frame body sent in `direction` with freshness `fresh`."""
        msg = direction + self.context + _FRESH.pack(fresh) + body
        return hmac.digest(self._key, msg, "sha256")[:MAC_SIZE]

    def control_mac(self, direction: bytes, datagram: bytes) -> bytes:
        """The truncated MAC of a UDP control datagram sent in `direction`."""
        return hmac.digest(self._key, DIR_CONTROL + direction + datagram, "sha256")[:MAC_SIZE]

    def seal(self, body: bytes) -> bytes:
        """`body` + the trailer of the next frame sent."""
        self.tx_fresh += 1
        fresh = self.tx_fresh
        return body + _LOW.pack(fresh & 0xFFFF) + self.mac(self.tx_dir, fresh, body)

    def open(self, sealed: bytes | memoryview) -> int:
        """AUTH_OK (the freshness accepted), AUTH_FAILED (short, or the MAC does not match) or AUTH_REPLAYED
        (the MAC holds, the freshness is not ahead) for a received body ending in its trailer."""
        n = len(sealed) - TRAILER
        if n < 0:
            return AUTH_FAILED
        body = bytes(sealed[:n])
        last = self.rx_fresh
        low = _LOW.unpack_from(sealed, n)[0]
        ahead = (low - last) & 0xFFFF
        fresh = last + ahead if 0 < ahead < 0x8000 else (last - ((last - low) & 0xFFFF)) % (1 << 64)
        if not hmac.compare_digest(self.mac(self.rx_dir, fresh, body), bytes(sealed[n + FRESH_SIZE:])):
            return AUTH_FAILED
        if fresh <= last:
            return AUTH_REPLAYED
        self.rx_fresh = fresh
        return AUTH_OK


__all__ = ["AUTH_FAILED", "AUTH_OK", "AUTH_REPLAYED", "TRAILER", "FrameAuth", "key_of_options", "new_key",
           "parse_key", "read_key_file"]
