"""Exception tree of the run-log layer."""

from __future__ import annotations

from pmsm_hil.errors import HilError


class RunLogError(HilError, RuntimeError):
    """The run logger cannot do what was asked; the message names the field or the cause."""


class LoggerDiedError(RunLogError):
    """The logger process exited or reported a fatal error; further submits are refused."""


class McapFormatError(RunLogError):
    """A file is not an MCAP file, or holds no recoverable data."""
