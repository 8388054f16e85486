"""Where the FMI 2.0 / 3.0 C headers are: the installed fmpy's `c-code` folder (fmpy ships the Modelica
Association's standard headers). The C loop (src/pmsm_hil/hil/runner/c/_build_loop.py, at build time: fmpy is a build
requirement) and the test suite's FMUs build against them. Standard library only: the build runs this file by
path, before the package is importable."""

from __future__ import annotations

import importlib.util
from pathlib import Path

#: headers the loop and the test FMUs include
FMI_HEADERS = ("fmi2Functions.h", "fmi2FunctionTypes.h", "fmi2TypesPlatform.h", "fmi3Functions.h",
               "fmi3FunctionTypes.h", "fmi3PlatformTypes.h")


def fmi_include_dir() -> Path:
    """The folder holding fmi2Functions.h, fmi3Functions.h and their type headers (fmpy/c-code), without
    importing fmpy; FileNotFoundError (one line saying what to install) when fmpy or a header is not there."""
    spec = importlib.util.find_spec("fmpy")
    if spec is None or spec.origin is None:
        raise FileNotFoundError("the FMI headers come from fmpy, which is not installed: pip install 'fmpy>=0.3.20' "
                                "(a build requirement of pmsm-hil's C loop)")
    folder = Path(spec.origin).resolve().parent / "c-code"
    missing = [h for h in FMI_HEADERS if not (folder / h).is_file()]
    if missing:
        raise FileNotFoundError(f"fmpy at {folder.parent} lacks the FMI headers {', '.join(missing)} in c-code/ "
                                "(reinstall fmpy>=0.3.20)")
    return folder
