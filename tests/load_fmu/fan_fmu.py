"""The test suite's load FMU (fmu_src/fan_load.c: fan law with a first-order lag, the model only: the FMI calls
are the example FMU's fmi_glue.h and fmi_unused.c), built at test time by the package's FMU builder
(src/pmsm_hil/hil/load_fmu/build.py: the host's C compiler against the FMI headers fmpy ships, zipped as an FMI 2.0
or 3.0 Co-Simulation FMU), as `hil fmu build` builds a user's."""

from __future__ import annotations

import math
import shutil
from collections.abc import Callable
from pathlib import Path

from pmsm_hil.hil import load_fmu
from pmsm_hil.hil.load_fmu.build import build_fmu

SRC = Path(__file__).resolve().parent / "fmu_src"
#: the example load FMU's sources: its FMI glue (fmi_glue.h) and the rest of the FMI API (fmi_unused.c)
EXAMPLE_SRC = Path(load_fmu.__file__).resolve().parent / "example_src"
#: the FMU's defaults (modelDescription start values): k [N·m·s²/rad²], tau [s]
K_DEFAULT, TAU_DEFAULT = 2.0e-4, 0.02


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
    text = (SRC / f"modelDescription_fmi{fmi}.xml").read_text(encoding="utf-8")
    if xml is not None:
        text = xml(text)
    defines = {"LOAD_FMI": fmi, "FAN_BAD": BAD[bad] if bad else 0, "FAN_BAD_IN_INIT": int(bad_in_init)}
    fmu = build_fmu([SRC / "fan_load.c", EXAMPLE_SRC / "fmi_unused.c"], text, out_dir / f"{name}.fmu", binary=binary,
                    extra_flags=(f"-I{EXAMPLE_SRC}",), defines=defines,
                    resources={"README.txt": "fan load test FMU\n"}, facts=(fmi, "fan_load"))
    return fmu


def rad_s(rpm: float) -> float:
    """rpm → rad/s."""
    return rpm * 2.0 * math.pi / 60.0
