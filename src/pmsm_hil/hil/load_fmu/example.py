"""The example load FMU users start from (`hil fmu example DIR`): its C source and model description (package
data in example_src/) written to a folder and built there; `build_folder` rebuilds a folder after an edit
(`hil fmu build DIR`)."""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path

from pmsm_hil.hil.load_fmu.build import FmuBuildError, build_fmu, description_facts

#: the example's C file (its modelIdentifier too, so the FMU is <NAME>.fmu)
EXAMPLE_NAME = "load_torque"
#: the model description of a folder `build_folder` builds
DESCRIPTION = "modelDescription.xml"
#: the macro that picks the FMI API in the example's source (-DLOAD_FMI=2 or 3)
FMI_MACRO = "LOAD_FMI"
#: the rest of the FMI API (stubs), so that tools loading every function (fmpy) load the FMU
UNUSED_API = "fmi_unused.c"
#: the FMI functions the runner calls, in terms of the model (included by the example's C file)
GLUE = "fmi_glue.h"


@dataclass(frozen=True, slots=True)
class ExampleFiles:
    """What `write_example` wrote: the C source, the model description and the built FMU."""

    source: Path
    description: Path
    fmu: Path


def _packaged(name: str) -> str:
    return (resources.files("pmsm_hil.hil.load_fmu") / "example_src" / name).read_text(encoding="utf-8")


def write_example(folder: Path, fmi: int = 2, *, overwrite: bool = False) -> ExampleFiles:
    """Write load_torque.c, fmi_glue.h, fmi_unused.c and the FMI `fmi` (2 or 3) modelDescription.xml into `folder`
    and build folder/load_torque.fmu; an existing file of another content is refused (FmuBuildError naming it) unless
    `overwrite`."""
    if fmi not in (2, 3):
        raise FmuBuildError(f"--fmi {fmi}: the example is built for FMI 2 or 3")
    folder.mkdir(parents=True, exist_ok=True)
    texts = {f"{EXAMPLE_NAME}.c": _packaged(f"{EXAMPLE_NAME}.c"), GLUE: _packaged(GLUE),
             UNUSED_API: _packaged(UNUSED_API),
             DESCRIPTION: _packaged(f"modelDescription_fmi{fmi}.xml")}
    for name, text in texts.items():
        path = folder / name
        if path.exists() and not overwrite and path.read_text(encoding="utf-8", errors="replace") != text:
            raise FmuBuildError(f"{path} exists and differs from the example: choose another folder or --overwrite")
    for name, text in texts.items():
        (folder / name).write_text(text, encoding="utf-8")
    return ExampleFiles(folder / f"{EXAMPLE_NAME}.c", folder / DESCRIPTION, build_folder(folder))


def build_folder(folder: Path) -> Path:
    """Build folder/<modelIdentifier>.fmu from every *.c file of `folder` and its modelDescription.xml, with
    -DLOAD_FMI=<the description's FMI major version>; returns the FMU's path."""
    description = folder / DESCRIPTION
    if not description.is_file():
        raise FmuBuildError(f"{description}: no model description in {folder} (`hil fmu example DIR` writes one)")
    sources = sorted(folder.glob("*.c"))
    if not sources:
        raise FmuBuildError(f"{folder}: no C source (*.c) to build")
    text = description.read_text(encoding="utf-8")
    fmi, ident = description_facts(text, str(description))
    return build_fmu(sources, text, folder / f"{ident}.fmu", defines={FMI_MACRO: fmi})


__all__ = ["DESCRIPTION", "EXAMPLE_NAME", "ExampleFiles", "build_folder", "write_example"]
