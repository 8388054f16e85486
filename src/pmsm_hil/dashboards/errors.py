"""Exception tree of the dashboards (`pmsm_hil.dashboards`): one base, reported by the CLI in one line."""

from __future__ import annotations

from pmsm_hil.errors import HilError


class DashboardError(HilError):
    """A dashboard, replay, report or browser step failed; the message names the option or file."""


class RerunUnavailableError(DashboardError):
    """The rerun-sdk package is missing or cannot start the requested sink (viewer, file, server)."""
