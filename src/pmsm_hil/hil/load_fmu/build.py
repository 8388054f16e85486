"""Building a Co-Simulation FMU from C: the source compiled with the host's C compiler against the FMI headers
of the installed fmpy (`headers.py`) and zipped with its model description as an FMI 2.0 or 3.0 FMU for Linux
x86-64 (`hil fmu example` / `hil fmu build`, and the test suite's FMUs). The FMI version and the binary's name (the
CoSimulation modelIdentifier) are read from the model description."""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import tempfile
import xml.etree.ElementTree as ET
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path

from pmsm_hil.hil.load_fmu.errors import LoadFmuError
from pmsm_hil.hil.load_fmu.headers import fmi_include_dir

#: binaries/<platform> of each FMI major version on x86-64 Linux
PLATFORM_DIR = {2: "linux64", 3: "x86_64-linux"}
#: the compiler's flags (the project's C standards); `extra_flags` of `build_fmu` come after them
CFLAGS = ("-std=c99", "-O2", "-fPIC", "-shared", "-Wall", "-Wextra", "-Werror")


class FmuBuildError(LoadFmuError):
    """An FMU could not be built: no C compiler, no FMI headers, a compile error, a bad model description."""


def host_compiler() -> str:
    """The host's C compiler: $CC, else gcc, else cc (FmuBuildError naming what to install when none is there)."""
    for name in (os.environ.get("CC"), "gcc", "cc"):
        if name and shutil.which(shlex.split(name)[0]):
            return name
    raise FmuBuildError("no C compiler: set CC or install gcc (e.g. apt-get install gcc) to build the FMU")


def description_facts(xml_text: str, where: str = "modelDescription.xml") -> tuple[int, str]:
    """(FMI major version 2 or 3, CoSimulation modelIdentifier) of a model description; FmuBuildError naming the
    attribute otherwise."""
    try:
        root = ET.fromstring(xml_text)
    except ET.ParseError as exc:
        raise FmuBuildError(f"{where}: not well-formed XML ({exc})") from None
    version = root.get("fmiVersion", "")
    major = version.split(".", 1)[0]
    if major not in ("2", "3"):
        raise FmuBuildError(f"{where}: fmiVersion {version!r}: an FMU is built for FMI 2.0 or 3.0")
    cs = root.find("CoSimulation")
    ident = cs.get("modelIdentifier", "") if cs is not None else ""
    if not ident or not ident.replace("_", "a").isalnum() or ident[0].isdigit():
        raise FmuBuildError(f"{where}: CoSimulation modelIdentifier {ident!r}: a C identifier is needed "
                            "(it names the binary)")
    return int(major), ident


def build_fmu(sources: Sequence[Path], model_description: str, out: Path, *, defines: Mapping[str, object] = {},
              extra_flags: Sequence[str] = (), binary: bool = True, resources: Mapping[str, str] | None = None,
              facts: tuple[int, str] | None = None) -> Path:
    """Compile `sources` into a shared library and zip it with the text `model_description` as the FMU `out`
    (modelDescription.xml, binaries/<platform>/<modelIdentifier>.so, `resources` {name: text} under
    resources/); `defines` become -DNAME=VALUE; `binary=False` leaves the binary out (a broken
    FMU for tests); `facts` (FMI major version, modelIdentifier) instead of reading them from the description (a
    deliberately broken one). Returns `out`; FmuBuildError with the compiler's first error line on failure."""
    fmi, ident = facts if facts is not None else description_facts(model_description)
    try:
        include = fmi_include_dir()
    except FileNotFoundError as exc:
        raise FmuBuildError(str(exc)) from None
    cc = host_compiler()
    out.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="hil-fmu-") as tmp:
        so = Path(tmp) / f"{ident}.so"
        cmd = [*shlex.split(cc), *CFLAGS, *(f"-D{k}={v}" for k, v in defines.items()), *extra_flags,
               f"-I{include}", *(str(s) for s in sources), "-o", str(so), "-lm"]
        if binary:
            done = subprocess.run(cmd, capture_output=True, text=True, check=False)
            if done.returncode != 0:
                lines = [ln for ln in (done.stderr or done.stdout).splitlines() if ln.strip()]
                first = next((ln for ln in lines if "error" in ln), lines[0] if lines else "no output")
                raise FmuBuildError(f"building {out.name}: {Path(cmd[0]).name} failed (exit {done.returncode}): "
                                    f"{first.strip()}")
        partial = out.with_name(out.name + ".partial")
        with zipfile.ZipFile(partial, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.writestr("modelDescription.xml", model_description)
            if binary:
                zf.write(so, f"binaries/{PLATFORM_DIR[fmi]}/{ident}.so")
            for name, text in (resources or {}).items():
                zf.writestr(f"resources/{name}", text)
        partial.replace(out)
    return out


__all__ = ["CFLAGS", "PLATFORM_DIR", "FmuBuildError", "build_fmu", "description_facts", "host_compiler"]
