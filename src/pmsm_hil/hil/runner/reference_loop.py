"""The hook of the test suite's reference loop: `--loop python` runs the Python period loop the C loop is proven
against (tests/oracle/closed_loop.py: records, frames and metrics bit for bit). The product has none: the C loop
runs every run.

The test suite registers it (`register_reference_loop`) and names its file in the environment variable
`PMSM_HIL_REFERENCE_LOOP` for the `hil` processes it starts; a run asking `--loop python` without it is a
ParameterError.
"""

from __future__ import annotations

import importlib.util
import os
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pmsm_hil.hil.errors import ParameterError

if TYPE_CHECKING:
    from pmsm_hil.hil.runner.block_sink import RunSink
    from pmsm_hil.hil.runner.loop_outcome import LoopOutcome
    from pmsm_hil.hil.runner.run_config import RunConfig
    from pmsm_hil.hil.runner.target_setup import TargetConnection

#: (run configuration, connection, controller id, block sink) -> the loop's outcome
ReferenceLoop = Callable[["RunConfig", "TargetConnection", int, "RunSink"], "LoopOutcome"]
#: environment variable: path of a Python file defining `run_reference_loop` (a ReferenceLoop)
ENV = "PMSM_HIL_REFERENCE_LOOP"

_registered: list[ReferenceLoop] = []


def register_reference_loop(fn: ReferenceLoop) -> None:
    """Make `--loop python` run `fn` in this process."""
    _registered[:] = [fn]


def reference_loop() -> ReferenceLoop | None:
    """The registered reference loop, or the one the environment names (loaded once), None in the product."""
    if _registered:
        return _registered[0]
    path = os.environ.get(ENV)
    if not path:
        return None
    spec = importlib.util.spec_from_file_location("pmsm_hil_reference_loop", Path(path))
    if spec is None or spec.loader is None or not Path(path).is_file():
        raise ParameterError(f"{ENV}: {path} is not a Python file")
    module: Any = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    fn: ReferenceLoop = module.run_reference_loop
    register_reference_loop(fn)
    return fn


def require_reference_loop() -> ReferenceLoop:
    """The reference loop; ParameterError saying `--loop python` is the test suite's when there is none."""
    fn = reference_loop()
    if fn is None:
        raise ParameterError("--loop python: the Python period loop is the test suite's reference "
                             "(tests/oracle/closed_loop.py), not part of the product; use --loop auto or native")
    return fn
