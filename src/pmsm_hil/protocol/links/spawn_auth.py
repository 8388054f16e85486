"""Authenticated frames for a spawned target (`hil run --target spawn`, a SIL target over UDP): on by default on
the UDP and serial links, with a fresh random key per run that the host hands the target over its stdin
(docs/protocol.md, "Authenticated frames").

`auth=off` in the link SPEC turns it off; a `key=HEX` given is used instead of a fresh one (and also goes over
stdin, not the target's command line); `keyfile=PATH` is read by both ends.
"""

from __future__ import annotations

from dataclasses import replace

from pmsm_hil.protocol.links.auth import key_of_options, new_key
from pmsm_hil.protocol.links.kinds import SpawnSpecs
from pmsm_hil.protocol.links.spec import parse_spec

#: link kinds whose frames can be authenticated
AUTH_KINDS = ("udp", "serial")


def _without_key(spec: str) -> str:
    head, *opts = spec.split(",")
    return ",".join([head, *(o for o in opts if o.partition("=")[0].strip() != "key")])


def spawn_auth(specs: SpawnSpecs) -> tuple[SpawnSpecs, bytes | None]:
    """The specs of a spawned target with authentication set up, and the key its stdin gets (None: none to
    hand over: a link kind without authentication, `auth=off`, or a `keyfile=` both ends read)."""
    ls = parse_spec(specs.host)
    if ls.kind.lower() not in AUTH_KINDS:
        return specs, None
    opts = dict(ls.options)
    if "keyfile" in opts:
        return specs, None
    key = key_of_options(opts) if "key" in opts or "auth" in opts else new_key()
    if key is None:  # auth=off
        return specs, None
    host = _without_key(specs.host) + f",key={key.hex()}"
    return replace(specs, host=host, target=_without_key(specs.target)), key


__all__ = ["AUTH_KINDS", "spawn_auth"]
