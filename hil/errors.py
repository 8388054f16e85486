"""Exception tree of the plant emulator and runner (`pmsm_hil.hil`)."""

from __future__ import annotations


class HilError(Exception):
    """Base of every error raised by `pmsm_hil.hil` for bad input or a failed run."""


class ParameterError(HilError, ValueError):
    """A motor, inverter or run parameter is missing, unknown or non-physical (message names it)."""


class SequenceError(HilError, ValueError):
    """A switching sequence is malformed (bad state code, durations not summing to Ts)."""


class InputFileError(HilError, ValueError):
    """A user file (CSV, preset, scenario, config) is malformed; the message names row/column or key."""


class PlantFaultError(HilError):
    """The plant tripped (overcurrent, overspeed) or the kernel rejected its input."""
