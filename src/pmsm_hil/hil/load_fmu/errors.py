"""Errors of a load FMU: one line each, naming the option, the file and the variable or call."""

from __future__ import annotations

from pmsm_hil.hil.errors import ParameterError, PlantFaultError


class LoadFmuError(ParameterError):
    """The FMU cannot be used as the load: missing or broken file, FMI version, interface, variable or parameter
    (found before the run)."""


class LoadFmuStepError(PlantFaultError):
    """The FMU failed during the run (instantiation, initialisation, a doStep, a non-finite torque)."""
