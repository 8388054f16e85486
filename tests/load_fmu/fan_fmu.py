"""The test suite's load FMU (fmu_src/fan_load.c: fan law with a first-order lag), built at test time with gcc
against the FMI headers fmpy ships (src/pmsm_hil/hil/load_fmu/headers.py) and zipped as an FMI 2.0 or 3.0 Co-Simulation
FMU."""

from __future__ import annotations

import math
import shutil
import subprocess
import zipfile
from collections.abc import Callable
from pathlib import Path

from pmsm_hil.hil.load_fmu.headers import fmi_include_dir

SRC = Path(__file__).resolve().parent / "fmu_src"
#: the FMU's defaults (modelDescription start values): k [N·m·s²/rad²], tau [s]
K_DEFAULT, TAU_DEFAULT = 2.0e-4, 0.02
#: binaries/<platform> of each FMI version on x86-64 Linux
PLATFORM_DIR = {2: "linux64", 3: "x86_64-linux"}


def fan_steady_torque(k: float, speed_rad_s: float) -> float:
    """The fan law's steady torque k·ω·|ω| [N·m]."""
    return k * speed_rad_s * abs(speed_rad_s)


def have_gcc() -> bool:
    """gcc is there to build the FMU."""
    return shutil.which("gcc") is not None


#: FAN_BAD of fmu_src/fan_load.c: how a misbehaving fan FMU misbehaves at t >= fail_at
BAD = {"segv": 1, "abort": 2, "stack": 3, "exit0": 4, "loop": 5, "block": 6, "huge": 7}


def build_fan_fmu(out_dir: Path, fmi: int = 2, *, name: str = "fan_load",
                  xml: Callable[[str], str] | None = None, binary: bool = True, bad: str | None = None,
                  bad_in_init: bool = False) -> Path:
    """Build the fan FMU (FMI `fmi` = 2 or 3) into out_dir/<name>.fmu; `xml` rewrites the model description
    (the tests' broken variants), `binary=False` leaves the binary out; `bad` (a BAD key) makes it misbehave at
    t >= fail_at in doStep, or in ExitInitializationMode with `bad_in_init`."""
    out_dir.mkdir(parents=True, exist_ok=True)
    so = out_dir / f"{name}-fmi{fmi}.so"
    subprocess.run(["gcc", "-std=c99", "-O2", "-fPIC", "-shared", "-Wall", "-Wextra", "-Werror", f"-DFAN_FMI={fmi}",
                    f"-DFAN_BAD={BAD[bad] if bad else 0}", f"-DFAN_BAD_IN_INIT={int(bad_in_init)}",
                    f"-I{fmi_include_dir()}", str(SRC / "fan_load.c"), "-o", str(so), "-lm"], check=True)
    text = (SRC / f"modelDescription_fmi{fmi}.xml").read_text(encoding="utf-8")
    if xml is not None:
        text = xml(text)
    fmu = out_dir / f"{name}.fmu"
    with zipfile.ZipFile(fmu, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("modelDescription.xml", text)
        if binary:
            zf.write(so, f"binaries/{PLATFORM_DIR[fmi]}/fan_load.so")
        zf.writestr("resources/README.txt", "fan load test FMU\n")
    return fmu


def rad_s(rpm: float) -> float:
    """rpm → rad/s."""
    return rpm * 2.0 * math.pi / 60.0
