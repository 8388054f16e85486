"""Build hook: package list from the mapped folders, and the C kernels compiled by cffi (API mode)."""

from pathlib import Path

from setuptools import setup

_BUILDERS = ["hil/native/_build_plant.py:ffibuilder", "sim_target/_build_firmware.py:ffibuilder",
             "hil/native/_build_loop.py:ffibuilder"]
_FOLDERS = ("hil", "protocol", "sim_target", "dashboards", "app")


def _packages() -> list[str]:
    """pmsm_hil, its own subpackages (pmsm_hil/testing, pmsm_hil/conformance) and every package below the
    mapped folders (see [tool.setuptools] package-dir)."""
    packages = [".".join(init.parent.parts) for init in sorted(Path("pmsm_hil").rglob("__init__.py"))]
    for folder in _FOLDERS:
        for init in sorted(Path(folder).rglob("__init__.py")):
            packages.append(".".join(("pmsm_hil", folder, *init.parent.relative_to(folder).parts)))
    return packages


setup(
    packages=_packages(),
    package_data={"pmsm_hil.hil.presets": ["*.toml", "*.csv"], "pmsm_hil.hil.scenarios": ["*.toml"],
                  "pmsm_hil.app.compare.presets": ["*.toml"],
                  "pmsm_hil.protocol": ["*.dbc"],
                  # the kernel headers and shared helpers kernel_build.py compiles a kind's kernel against
                  "pmsm_hil.hil": ["native/kernels/*.h", "native/kernels/gate_edges.c",
                                   "native/kernels/dq_segment.c"]},
    cffi_modules=[b for b in _BUILDERS if Path(b.split(":")[0]).exists()],
)
