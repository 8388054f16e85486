"""Exception tree of the plant emulator and runner (`pmsm_hil.hil`); `HilError` is the package's one root
(`pmsm_hil.errors`), re-exported here for the existing imports."""

from __future__ import annotations

from pmsm_hil.errors import HilError

__all__ = ["HilError", "InputFileError", "ParameterError", "PlantFaultError", "SequenceError"]


class ParameterError(HilError, ValueError):
    """A motor, inverter or run parameter is missing, unknown or non-physical (message names it). `key`: the run
    option the value came from when the raiser knows it (`RunConfig.from_options` then names where the value was
    set: the command line, a config file, a sweep's grid key, ...)."""

    def __init__(self, *args: object, key: str | None = None) -> None:
        super().__init__(*args)
        self.key = key


class SequenceError(HilError, ValueError):
    """A switching sequence is malformed (bad state code, durations not summing to Ts)."""


class InputFileError(HilError, ValueError):
    """A user file (CSV, preset, scenario, config) is malformed; the message names row/column or key."""


class PlantFaultError(HilError):
    """The plant tripped (overcurrent, overspeed) or the kernel rejected its input."""
