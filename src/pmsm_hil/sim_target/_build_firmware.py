"""cffi (API mode) builder of the C reference firmware: extension `pmsm_hil.sim_target._firmware`.

The cdef is taken from the headers only (src/pmsm_hil/hil/cdef_extract.py): firmware_stub/include/*.h and the generated
hil_ids.h for the firmware API, firmware_py.h (this folder) for the extension's glue; cffi checks the layouts
against the real headers at build time (tests/plant/test_cdef_extract.py fails on a restated declaration). Build with
`.venv/bin/pip install --no-build-isolation -e .` (setup.py lists this builder in cffi_modules).
"""
from __future__ import annotations

import os
import runpy
from pathlib import Path
from types import SimpleNamespace

from cffi import FFI

#: the repository (src/pmsm_hil/sim_target/ -> ../../..)
ROOT = Path(__file__).resolve().parents[3]
FIRMWARE = ROOT / "firmware_stub"

# The firmware's strict flags also hold for the cffi-generated wrapper (checked with gcc 12).
STRICT_FLAGS = [
    "-std=c99",
    "-Wall",
    "-Wextra",
    "-Werror",
    "-Wdouble-promotion",
    "-fsingle-precision-constant",
    "-O2",
]

#: src/pmsm_hil/hil/cdef_extract.py by path (this script runs at build time, before the package is importable)
_X = SimpleNamespace(**runpy.run_path(str(Path(__file__).resolve().parents[1] / "hil" / "cdef_extract.py")))
_INCLUDE = FIRMWARE / "include"
_HERE = Path(__file__).resolve().parent

#: the firmware API as cffi reads it, from the headers only: the return codes and sizes, the measurement and
#: command records, the state and controller-table entry cut down to the fields Python reads (the rest is the
#: controllers' private state), the configuration and step functions, and the extension's own glue (firmware_py.h)
CDEF = (_X.cffi_constants(_INCLUDE / "hil_fw_types.h", "HIL_FW_")
        + _X.cffi_constants(FIRMWARE / "generated" / "hil_ids.h", names=["HIL_FW_CTRL_COUNT", "HIL_FW_P_COUNT"])
        + _X.declarations(_INCLUDE / "hil_fw_types.h", ["hil_fw_meas_t", "hil_fw_cmd_t"])
        + _X.declarations(_INCLUDE / "hil_fw_state.h", ["hil_fw_state_t", "hil_fw_init", "hil_fw_set_param",
                                                        "hil_fw_get_param", "hil_fw_select_controller",
                                                        "hil_fw_set_setpoint"],
                          partial={"hil_fw_state_t": ["controller_id", "enable", "mode", "reference"]})
        + _X.declarations(_INCLUDE / "hil_fw_controllers.h", ["hil_fw_controller_t", "hil_fw_controller_get",
                                                              "hil_fw_controller_implemented",
                                                              "hil_fw_controller_name"],
                          partial={"hil_fw_controller_t": ["name", "id", "phases", "params"]})
        + _X.declarations(_INCLUDE / "hil_fw_step.h", ["hil_fw_stage_measure", "hil_fw_stage_reference",
                                                       "hil_fw_stage_predict", "hil_fw_step"])
        + _X.declarations(_INCLUDE / "hil_fw_profile.h", ["hil_fw_step_profiled"])
        + _X.declarations(_HERE / "firmware_py.h", ["hil_fw_py_out_t", "hil_fw_py_step"]))

PREAMBLE = """
#include "hil_fw.h"
#include "firmware_py.h"
"""


def _rel(path: Path) -> str:
    """Path relative to the working directory when possible (setuptools prefers relative sources)."""
    try:
        return os.path.relpath(path)
    except ValueError:
        return str(path)


ffibuilder = FFI()
ffibuilder.cdef(CDEF)
ffibuilder.set_source(
    "pmsm_hil.sim_target._firmware",
    PREAMBLE,
    sources=[_rel(p) for p in sorted((FIRMWARE / "src").glob("*.c"))],
    include_dirs=[_rel(FIRMWARE / "include"), _rel(FIRMWARE / "generated"), _rel(_HERE)],
    extra_compile_args=STRICT_FLAGS,
    libraries=["m"],
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
