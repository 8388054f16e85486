"""Firmware CI in pytest: the `hil` fixture, signal assertions with plots on failure (docs/ci.md).

This module is the pytest plugin (entry point `pytest11`: options `--hil-target` (checked at start-up), `--hil-motor`,
`--hil-controller`, `--hil-out`; fixtures `hil`, `hil_session`) and the API a test imports::

    from pmsm_hil.testing import assert_settles, stepinfo

    def test_speed_step(hil):
        r = hil.run(scenario="speed-step", duration=0.3)
        assert r.end_code == 0, r.end_reason
        assert_settles(r.signal("speed_rpm"), to=1500, tol=15, within=0.1, t0=0.22)

The assertions, numpy and the runner load on first use (the plugin is imported by every pytest run).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pmsm_hil.lazy_names import lazy_getattr
from pmsm_hil.testing.plugin import hil, hil_session, pytest_addoption, pytest_configure

if TYPE_CHECKING:
    from pmsm_hil.testing.report import PLOT_PROPERTY
    from pmsm_hil.testing.runs import HilResult, HilRunError, SetpointNotHeldError
    from pmsm_hil.testing.signals import (
        Signal,
        SignalAssertionError,
        StepInfo,
        assert_below,
        assert_is_constant,
        assert_ripple_below,
        assert_settles,
        assert_thd_below,
        stepinfo,
    )

_LAZY = {
    **dict.fromkeys(("Signal", "SignalAssertionError", "StepInfo", "assert_below", "assert_is_constant",
                     "assert_ripple_below", "assert_settles", "assert_thd_below", "stepinfo"),
                    "pmsm_hil.testing.signals"),
    "HilResult": "pmsm_hil.testing.runs",
    "HilRunError": "pmsm_hil.testing.runs",
    "SetpointNotHeldError": "pmsm_hil.testing.runs",
    "PLOT_PROPERTY": "pmsm_hil.testing.report",
}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())


__all__ = ["PLOT_PROPERTY", "HilResult", "HilRunError", "SetpointNotHeldError", "Signal", "SignalAssertionError",
           "StepInfo",
           "assert_below", "assert_is_constant", "assert_ripple_below", "assert_settles", "assert_thd_below",
           "hil", "hil_session", "pytest_addoption", "pytest_configure", "stepinfo"]
