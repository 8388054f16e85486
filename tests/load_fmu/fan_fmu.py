"""The test suite's load FMU (fmu_src/fan_load.c: fan law with a first-order lag, the model only: the FMI calls
are the example FMU's fmi_glue.h and fmi_unused.c), built at test time by the package's FMU builder
(src/pmsm_hil/hil/load_fmu/build.py: the host's C compiler against the FMI headers fmpy ships, zipped as an FMI 2.0
or 3.0 Co-Simulation FMU), as `hil fmu build` builds a user's. Each FMU is built once per content (`fmu_cache_key`)
and copied from the per-user cache afterwards: the suite asks for the same FMUs in many tests and sessions."""

from __future__ import annotations

import functools
import hashlib
import math
import os
import shlex
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

from pmsm_hil.hil import load_fmu
from pmsm_hil.hil.load_fmu import build as fmu_build
from pmsm_hil.hil.load_fmu.build import build_fmu
from pmsm_hil.hil.load_fmu.headers import fmi_include_dir
from pmsm_hil.sim_target.fw_build import cache_dir
from pmsm_hil.sim_target.fw_cache import tree_digest
from tests.cache_prune import remove_stale

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
    out = out_dir / f"{name}.fmu"
    cached = cache_dir() / "test-fmu" / f"{fmu_cache_key(fmi, text, defines, binary)}.fmu"
    if not cached.is_file():
        cached.parent.mkdir(parents=True, exist_ok=True)
        part = cached.with_name(f"{cached.stem}.{os.getpid()}.partial")
        build_fmu([SRC / "fan_load.c", EXAMPLE_SRC / "fmi_unused.c"], text, part, binary=binary,
                  extra_flags=(f"-I{EXAMPLE_SRC}",), defines=defines,
                  resources={"README.txt": "fan load test FMU\n"}, facts=(fmi, "fan_load"))
        part.replace(cached)  # whole or absent for a concurrent worker
        remove_stale(cached.parent, "*.fmu")
    else:
        cached.touch()  # used: not stale
    out_dir.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(cached, out)
    return out


def fmu_cache_key(fmi: int, xml_text: str, defines: dict[str, int], binary: bool) -> str:
    """The cache key of a fan FMU: sha256 of everything its build reads — the sources (fmu_src/, the example's
    glue), the FMI headers, the builder module (flags, layout), the compiler and its version, the environment's
    CFLAGS — and of the build's arguments."""
    h = hashlib.sha256()
    for part in (str(fmi), xml_text, repr(sorted(defines.items())), str(binary), tree_digest(SRC),
                 tree_digest(EXAMPLE_SRC), tree_digest(fmi_include_dir()),
                 hashlib.sha256(Path(fmu_build.__file__).read_bytes()).hexdigest(), _compiler_version(),
                 os.environ.get("CFLAGS", "")):
        h.update(part.encode() + b"\0")
    return h.hexdigest()[:32]


@functools.cache
def _compiler_version() -> str:
    """The FMU builder's compiler (`host_compiler`: $CC, gcc or cc) with its path and `--version` line."""
    cc = fmu_build.host_compiler()
    exe = shutil.which(shlex.split(cc)[0]) or cc
    done = subprocess.run([exe, "--version"], capture_output=True, text=True, check=False, timeout=60)
    return f"{cc} {os.path.realpath(exe)} {done.stdout.splitlines()[:1]}"


def rad_s(rpm: float) -> float:
    """rpm → rad/s."""
    return rpm * 2.0 * math.pi / 60.0
