"""Errors of a load FMU: one line each, naming the option, the file and the variable or call."""

from __future__ import annotations

from typing import Any

from pmsm_hil.hil.errors import ParameterError, PlantFaultError


class LoadFmuError(ParameterError):
    """The FMU cannot be used as the load: missing or broken file, FMI version, interface, variable or parameter
    (found before the run)."""


class LoadFmuStepError(PlantFaultError):
    """The FMU failed during the run (instantiation, initialisation, a doStep, a non-finite torque)."""


class LoadFmuCrashError(LoadFmuStepError):
    """The FMU's own process crashed, exited or hung while the FMU was instantiated or initialised (before the
    first period): a safety stop (exit 3), not a bad file. `metrics`: metrics.json `load_fmu` of the instance."""

    def __init__(self, message: str, metrics: dict[str, Any]) -> None:
        super().__init__(message)
        self.metrics = metrics
