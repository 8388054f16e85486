"""Link SPEC strings: "NAME[:CHANNEL][,key=value...]" parsed into a `LinkSpec` (docs/protocol.md, "Link specs")."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from pmsm_hil.protocol.errors import LinkSpecError

Role = Literal["host", "target"]

#: options that are rates: a positive whole number in these units (checked when the SPEC is parsed)
RATE_OPTIONS = {"bitrate": "bit/s", "data_bitrate": "bit/s", "baudrate": "baud"}
#: options kept as the text given (a hex key's leading zeros, a path): never read as numbers or booleans
TEXT_OPTIONS = ("key", "keyfile")
#: options whose value is secret: `redact_spec` hides it wherever a SPEC is shown or stored
SECRET_OPTIONS = ("key",)


@dataclass(frozen=True, slots=True)
class LinkSpec:
    """Parsed SPEC string: kind (interface name), channel, options for can.Bus."""

    kind: str
    channel: str | None
    options: dict[str, Any] = field(default_factory=dict)


def _option_value(text: str) -> Any:
    low = text.lower()
    if low in ("true", "yes", "on"):
        return True
    if low in ("false", "no", "off"):
        return False
    for conv in (int, float):
        try:
            return conv(text)
        except ValueError:
            pass
    return text


def parse_spec(spec: str) -> LinkSpec:
    """Split "NAME[:CHANNEL][,key=value...]"; raises LinkSpecError naming the bad part."""
    if not isinstance(spec, str) or not spec.strip():
        raise LinkSpecError(f"link spec {spec!r} is empty")
    head, *opts = spec.strip().split(",")
    name, sep, channel = head.partition(":")
    name = name.strip()
    if not name:
        raise LinkSpecError(f"link spec {spec!r}: missing interface name before ':'")
    if sep and not channel:
        raise LinkSpecError(f"link spec {spec!r}: empty channel after '{name}:'")
    options: dict[str, Any] = {}
    for opt in opts:
        key, eq, value = opt.partition("=")
        if not eq or not key.strip():
            raise LinkSpecError(f"link spec {spec!r}: option {opt!r} is not key=value")
        opt_name = key.strip()
        options[opt_name] = value.strip() if opt_name in TEXT_OPTIONS else _option_value(value.strip())
    for key, unit in RATE_OPTIONS.items():
        if key in options:
            options[key] = _rate(spec, key, options[key], unit)
    return LinkSpec(name, channel or None, options)


def redact_spec(spec: str) -> str:
    """`spec` with the value of every secret option (`key=`) replaced by `***`: what is printed, logged or
    written to metrics.json and the MCAP metadata."""
    if not isinstance(spec, str):
        return spec
    head, *opts = spec.split(",")
    for i, opt in enumerate(opts):
        name, eq, _ = opt.partition("=")
        if eq and name.strip() in SECRET_OPTIONS:
            opts[i] = f"{name}=***"
    return ",".join([head, *opts])


def _rate(spec: str, key: str, value: Any, unit: str) -> int:
    """A rate option as a positive int (1e6 and 1000000 alike); LinkSpecError naming the option otherwise."""
    if isinstance(value, int | float) and not isinstance(value, bool) and value > 0 and float(value).is_integer():
        return int(value)
    raise LinkSpecError(f"link spec {spec!r}: {key} must be a positive whole number of {unit}, got {value!r}")
