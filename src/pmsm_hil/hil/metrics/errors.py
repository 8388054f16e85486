"""Exception tree of the metrics layer."""

from __future__ import annotations

from pmsm_hil.errors import HilError


class MetricsError(HilError, ValueError):
    """Bad input to a metric; the message names the offending field."""


class MetricsWindowError(MetricsError):
    """The metrics window is too short (or empty) for the requested metric."""
