"""cffi (API mode) builder for the plant kernel: extension `pmsm_hil.hil._plant_native`."""

from __future__ import annotations

import runpy
from pathlib import Path
from types import SimpleNamespace

from cffi import FFI

_HERE = Path(__file__).resolve().parent
#: the plant kernels' own folder (this one; the loop's C is in src/pmsm_hil/hil/runner/c)
_KERNELS = _HERE


#: src/pmsm_hil/hil/cdef_extract.py by path (this script runs at build time, before the package is importable)
_X = SimpleNamespace(**runpy.run_path(str(_HERE.parent / "cdef_extract.py")))
#: what every kernel's extension declares first: the period stats, the mechanics, the sample and the opaque kernel
#: table (the same as kernel_build.common_cdef: this script cannot import the package)
CDEF_COMMON = (_X.declarations(_KERNELS / "gate_edges.h", ["ge_period_stats_t", "ge_legs_t"])
               + _X.cffi_constants(_KERNELS / "mechanics.h", "MECH_")
               + _X.declarations(_KERNELS / "mechanics.h", ["mech_params_t", "mech_state_t", "mech_load_t",
                                                            "mech_step", "mech_hold"])
               + _X.declarations(_KERNELS / "machine_kernel.h", ["mk_sample_t", "mk_kernel_t"], opaque=["mk_kernel_t"]))
#: the three-phase kernel (plant.h) and the dual three-phase kernel (plant6.h), taken from their headers
CDEF = _X.declarations(_KERNELS / "plant.h", ["pl_params_t", "pl_state_t", "pl_period_stats_t", "pl_advance",
                                           "pl_torque", "pl_phase_currents", "pl_kernel"])
CDEF6 = _X.declarations(_KERNELS / "plant6.h", ["p6_params_t", "p6_state_t", "p6_period_stats_t", "p6_advance",
                                             "p6_torque", "p6_phase_currents", "p6_code_voltage", "p6_kernel"])
#: the saturated PMSM of a flux map (fluxmap.h, kind "pmsm-fluxmap")
CDEF_FM = _X.declarations(_KERNELS / "fluxmap.h", ["fm_params_t", "fm_state_t", "fm_period_stats_t", "fm_flux",
                                                "fm_currents", "fm_advance", "fm_sample", "fm_kernel"])
#: the induction machine kernel (im.h)
CDEF_IM = _X.declarations(_KERNELS / "im.h", ["im_params_t", "im_state_t", "im_period_stats_t", "im_advance",
                                           "im_sample", "im_kernel"])


def _source(name: str) -> str:
    """Source path, relative to the working directory when possible (setuptools wants that)."""
    path = _KERNELS / name
    return str(path.relative_to(Path.cwd())) if path.is_relative_to(Path.cwd()) else str(path)


#: the plant kernels and their shared helpers (nothing of the loop: tests/test_layers.py)
PLANT_SOURCES = ("dq_segment.c", "gate_edges.c", "mechanics.c", "plant.c", "plant6.c", "fluxmap.c", "im.c")

ffibuilder = FFI()
ffibuilder.cdef(CDEF_COMMON + CDEF + CDEF6 + CDEF_FM + CDEF_IM)
ffibuilder.set_source(
    "pmsm_hil.hil._plant_native",
    '#include "plant.h"\n#include "plant6.h"\n#include "fluxmap.h"\n#include "im.h"',
    sources=[_source(name) for name in PLANT_SOURCES],
    include_dirs=[str(_KERNELS)],
    # the native loop calls these kernels too: no FMA contraction and no sin/cos fusion, so its records equal the
    # Python loop's bit for bit on every architecture
    extra_compile_args=["-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion", "-ffp-contract=off",
                        "-fno-builtin-sin", "-fno-builtin-cos"],
    libraries=["m"],
)

if __name__ == "__main__":
    ffibuilder.compile(verbose=True)
