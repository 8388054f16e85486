"""The bench layer's error."""

from __future__ import annotations

from pmsm_hil.errors import HilError


class BenchError(HilError, RuntimeError):
    """A bench could not be leased, flashed or reached; the message names the place."""


class BoardSilentError(BenchError):
    """The place's board gave no heartbeat after flashing and reset (a safety stop of the run: exit 3)."""
