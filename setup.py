"""Build hook: the package list from src/ (every folder with an __init__.py), and the C extensions compiled by cffi
(API mode): the plant kernels, the reference firmware, the period loop and the wire links of the python-can buses."""

from pathlib import Path

from setuptools import find_packages, setup

_BUILDERS = ["src/pmsm_hil/hil/kernels/_build_plant.py:ffibuilder",
             "src/pmsm_hil/sim_target/_build_firmware.py:ffibuilder",
             "src/pmsm_hil/hil/runner/c/_build_loop.py:ffibuilder",
             "src/pmsm_hil/protocol/links/_build_wire.py:ffibuilder"]

setup(
    packages=find_packages(where="src"),
    package_data={"pmsm_hil.hil.presets": ["*.toml", "*.csv"], "pmsm_hil.hil.scenarios": ["*.toml"],
                  "pmsm_hil.app.compare.presets": ["*.toml"],
                  "pmsm_hil.protocol": ["*.dbc"],
                  # the example load FMU's C source and model descriptions (`hil fmu example`)
                  "pmsm_hil.hil.load_fmu": ["example_src/*.c", "example_src/*.h", "example_src/*.xml"],
                  # the virtual board's instruction counter (built on first use) and its board descriptions
                  "pmsm_hil.sim_target.stm32g4": ["c/*.c", "boards/*.toml"],
                  # the kernel headers and shared helpers kernel_build.py compiles a kind's kernel against
                  "pmsm_hil.hil": ["kernels/*.h", "kernels/gate_edges.c", "kernels/dq_segment.c"]},
    cffi_modules=[b for b in _BUILDERS if Path(b.split(":")[0]).exists()],
)
