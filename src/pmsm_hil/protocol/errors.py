"""Exception tree of the protocol layer (codec, links, link budget)."""

from __future__ import annotations

from pmsm_hil.errors import HilError


class ProtocolError(HilError):
    """Base of every error raised by `pmsm_hil.protocol`; the message names the message/field."""


class DecodeError(ProtocolError, ValueError):
    """A frame cannot be decoded (strict API only; the hot-path decoder counts instead)."""


class EncodeError(ProtocolError, ValueError):
    """A value cannot be encoded (out of range, wrong length); names the field."""


class DatabaseError(ProtocolError):
    """The DBC does not have the layout the codec expects."""


class LinkError(ProtocolError):
    """A link cannot be opened or used."""


class LinkSpecError(LinkError, ValueError):
    """A link SPEC string is malformed; names the offending part."""


class BudgetError(ProtocolError, ValueError):
    """Invalid link-budget arguments (unknown link, non-positive bit rate, ...)."""
