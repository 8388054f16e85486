"""Keys of the authenticated frames on the UDP and serial links, in the spirit of AUTOSAR SecOC (docs/protocol.md,
"Authenticated frames"). The authentication itself is C (firmware_stub/target/hil_auth.c), used by the hiludp and
hilserial buses (wire_bus.py), the period loop and the targets alike; this module reads and makes the keys.

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

import secrets
from pathlib import Path
from typing import Any

from pmsm_hil.protocol.errors import LinkSpecError

KEY_MIN, KEY_MAX = 16, 64
FRESH_SIZE = 2
MAC_SIZE = 4
#: bytes the authentication adds to every frame (freshness low bits + truncated MAC)
TRAILER = FRESH_SIZE + MAC_SIZE
#: the spawned-target key length [bytes]
SPAWN_KEY_BYTES = 32


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


__all__ = ["KEY_MAX", "KEY_MIN", "MAC_SIZE", "TRAILER", "key_of_options", "new_key", "parse_key", "read_key_file"]
