"""The bench layer's error."""

from __future__ import annotations

from pmsm_hil.errors import HilError


class BenchError(HilError, RuntimeError):
    """A bench could not be leased, flashed or reached; the message names the place."""
