"""Build a machine kind's C kernel that is not bundled (a user's, or a test's) into a cffi extension module and
import it: the same strict flags as the bundled plant kernels (src/pmsm_hil/hil/kernels/_build_plant.py), the kernel
headers (machine_kernel.h, gate_edges.h, dq_segment.h) on the include path, the shared gate-edge and dq helpers linked
in.

The module's ``lib`` then offers the kernel's functions named in `cdef`, among them the one returning its
machine-kernel table (`PlantBase.KERNEL_TABLE`), and ``ffi`` its structs for `PlantBase.NATIVE_MODULE`.
"""

from __future__ import annotations

import hashlib
import importlib.util
from pathlib import Path
from types import ModuleType

from pmsm_hil.hil.cdef_extract import cffi_constants, declarations
from pmsm_hil.hil.errors import ParameterError

#: the kernel headers and shared helpers (hil/kernels, installed with the package)
NATIVE_DIR = Path(__file__).resolve().parent / "kernels"
#: C sources every kernel may use: gate edges, dead time, the closed-form dq segment and the mechanics
SHARED_SOURCES = ("gate_edges.c", "dq_segment.c", "mechanics.c")
#: the bundled kernels' flags: no FMA contraction and no sin/cos fusion (the native loop's records equal the Python
#: loop's bit for bit), warnings are errors
KERNEL_FLAGS = ("-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion", "-ffp-contract=off",
                "-fno-builtin-sin", "-fno-builtin-cos")


def common_cdef() -> str:
    """What every kernel's cdef starts with, from the headers: `ge_period_stats_t`, the mechanics (`mech_params_t`,
    `mech_state_t`, `mech_load_t`, `mech_step`, `mech_hold`, the MECH_ modes), `mk_sample_t`, and the opaque
    `mk_kernel_t` (the bundled plant extension takes the same from the same headers,
    src/pmsm_hil/hil/kernels/_build_plant.py)."""
    return (declarations(NATIVE_DIR / "gate_edges.h", ["ge_period_stats_t", "ge_legs_t"])
            + cffi_constants(NATIVE_DIR / "mechanics.h", "MECH_")
            + declarations(NATIVE_DIR / "mechanics.h", ["mech_params_t", "mech_state_t", "mech_load_t", "mech_step",
                                                         "mech_hold"])
            + declarations(NATIVE_DIR / "machine_kernel.h", ["mk_sample_t", "mk_kernel_t"], opaque=["mk_kernel_t"]))


def build_kernel_module(name: str, kernel_c: Path, cdef: str, build_dir: Path) -> ModuleType:
    """Compile the kernel's one C file `kernel_c` (structs, functions and its machine-kernel table) with the
    shared helpers into the extension `name` under `build_dir` and import it; `cdef` declares what Python uses
    (cffi syntax: the params/state structs, the advance, sample and table functions, best taken from the C file by
    `cdef_extract.declarations(kernel_c, names)`; `ge_period_stats_t`, the mechanics' structs, `mk_sample_t` and
    `mk_kernel_t` are declared before it: `common_cdef`). Rebuilt only when the C file, the cdef or a kernel header
    changed. ParameterError naming the file when it is missing; a compiler error is raised with the compiler's own
    message."""
    from cffi import FFI

    kernel_c = Path(kernel_c)
    if not kernel_c.is_file():
        raise ParameterError(f"kernel source {kernel_c} not found")
    if not name.isidentifier():
        raise ParameterError(f"kernel module name {name!r} must be a Python identifier")
    text = kernel_c.read_text(encoding="utf-8")
    digest = hashlib.sha256(cdef.encode() + text.encode())
    for path in [*(NATIVE_DIR / s for s in SHARED_SOURCES), *sorted(NATIVE_DIR.glob("*.h"))]:
        digest.update(path.read_bytes())
    out = Path(build_dir) / f"{name}_{digest.hexdigest()[:12]}"
    out.mkdir(parents=True, exist_ok=True)
    built = sorted(out.glob(f"{name}*.so"))
    if not built:
        builder = FFI()
        builder.cdef(common_cdef() + cdef)
        builder.set_source(name, text, sources=[str(NATIVE_DIR / s) for s in SHARED_SOURCES],
                           include_dirs=[str(kernel_c.resolve().parent), str(NATIVE_DIR)],
                           extra_compile_args=list(KERNEL_FLAGS), libraries=["m"])
        try:
            built = [Path(builder.compile(tmpdir=str(out)))]
        except Exception as exc:  # cffi's VerificationError carries the compiler's message
            raise ParameterError(f"kernel {kernel_c}: the build failed: {exc}") from None
    spec = importlib.util.spec_from_file_location(name, built[0])
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load the kernel module {built[0]}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


__all__ = ["KERNEL_FLAGS", "NATIVE_DIR", "SHARED_SOURCES", "build_kernel_module", "common_cdef"]
