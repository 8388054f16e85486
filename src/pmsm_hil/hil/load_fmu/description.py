"""A load FMU's model description, read and checked with fmpy before the run: FMI version (2.0 or 3.0),
Co-Simulation interface, a binary for this platform, the speed input and torque output (name, causality, type)
and the parameters `--load-fmu-set` writes. Every problem is one `LoadFmuError` line naming the file."""

from __future__ import annotations

import math
import zipfile
from dataclasses import dataclass
from typing import Any
from xml.etree import ElementTree

from pmsm_hil.hil.load_fmu.errors import LoadFmuError
from pmsm_hil.hil.load_fmu.spec import LoadFmuSpec

#: value kinds of loop_fmu.h (NL_FMU_REAL, NL_FMU_INTEGER, NL_FMU_BOOLEAN) by the FMI type names
REAL, INTEGER, BOOLEAN = 0, 1, 2
_KINDS = {"Real": REAL, "Float64": REAL, "Integer": INTEGER, "Int32": INTEGER, "Boolean": BOOLEAN}
_REAL_TYPES = ("Real", "Float64")
#: the range of an Integer / Int32 parameter (fmi2Integer, fmi3Int32)
INT32_MIN, INT32_MAX = -(2**31), 2**31 - 1


@dataclass(frozen=True, slots=True)
class LoadFmuParam:
    """A parameter to set before initialisation: its value reference, kind (REAL/INTEGER/BOOLEAN) and value."""

    name: str
    vr: int
    kind: int
    value: float


@dataclass(frozen=True, slots=True)
class LoadFmuModel:
    """What the run needs of a checked load FMU."""

    spec: LoadFmuSpec
    fmi_version: int
    model_name: str
    token: str
    model_identifier: str
    binary_member: str
    vr_speed: int
    vr_torque: int
    params: tuple[LoadFmuParam, ...]

    def as_metrics(self) -> dict[str, Any]:
        """metrics.json `load_fmu`: which load ran (path, FMI version, model, guid / instantiationToken, ...)."""
        token_key = "instantiation_token" if self.fmi_version == 3 else "guid"
        return {"path": str(self.spec.path.resolve()), "fmi_version": f"{self.fmi_version}.0",
                "model_name": self.model_name, token_key: self.token, "model_identifier": self.model_identifier,
                "speed": self.spec.speed, "torque": self.spec.torque,
                "parameters": {p.name: p.value for p in self.params}}


def _fmpy() -> Any:
    try:
        import fmpy
    except ImportError:
        raise LoadFmuError("--load-fmu needs fmpy (pip install 'pmsm-hil[fmu]')") from None
    return fmpy


def binary_dir(fmi_version: int) -> str:
    """The FMU's folder of binaries for this platform (FMI 2: binaries/linux64, FMI 3: binaries/x86_64-linux)."""
    fmpy = _fmpy()
    return f"binaries/{fmpy.platform if fmi_version == 2 else fmpy.platform_tuple}"


def read_load_fmu(spec: LoadFmuSpec) -> LoadFmuModel:
    """Read and check the FMU `spec` names; LoadFmuError (one line) for anything the run could not use."""
    where = f"--load-fmu {spec.path}"
    if not spec.path.is_file():
        raise LoadFmuError(f"{where}: no such file")
    if not zipfile.is_zipfile(spec.path):
        raise LoadFmuError(f"{where}: not an FMU (not a zip archive)")
    version = _fmi_version(spec)
    if version.split(".")[0] not in ("2", "3"):
        raise LoadFmuError(f"{where}: FMI version {version or '?'} (FMI 2.0 and 3.0 Co-Simulation are supported)")
    fmpy = _fmpy()
    from fmpy.model_description import read_model_description

    try:
        md = read_model_description(str(spec.path), validate=True)
    except Exception as exc:  # fmpy raises plain exceptions (schema, XML, missing modelDescription.xml)
        problems = getattr(exc, "problems", None)  # fmpy's ValidationError: the schema's findings
        text = "; ".join(str(p) for p in problems) if problems else " ".join(str(exc).split())
        raise LoadFmuError(f"{where}: model description unreadable: {text or type(exc).__name__}") from None
    fmi = int(version.split(".")[0])
    if md.coSimulation is None:
        raise LoadFmuError(f"{where}: no Co-Simulation interface (Model Exchange FMUs are not supported)")
    ident = str(md.coSimulation.modelIdentifier)
    member = f"{binary_dir(fmi)}/{ident}.so"
    with zipfile.ZipFile(spec.path) as zf:
        if member not in zf.namelist():
            raise LoadFmuError(f"{where}: no binary {member} for this platform ({fmpy.platform_tuple})")
    by_name = {v.name: v for v in md.modelVariables}
    speed = _variable(by_name, spec.speed, "input", "speed", where)
    torque = _variable(by_name, spec.torque, "output", "torque", where)
    params = tuple(_param(by_name, name, value, where) for name, value in spec.params)
    return LoadFmuModel(spec, fmi, str(md.modelName), str(md.guid or ""), ident, member,
                        int(speed.valueReference), int(torque.valueReference), params)


def _fmi_version(spec: LoadFmuSpec) -> str:
    """The fmiVersion attribute of the FMU's modelDescription.xml (read before fmpy validates it against the
    schema of that version, so another version is named as such)."""
    where = f"--load-fmu {spec.path}"
    try:
        with zipfile.ZipFile(spec.path) as zf, zf.open("modelDescription.xml") as f:
            for _event, element in ElementTree.iterparse(f, events=("start",)):
                return str(element.get("fmiVersion", ""))
    except KeyError:
        raise LoadFmuError(f"{where}: no modelDescription.xml in the archive") from None
    except (ElementTree.ParseError, zipfile.BadZipFile, OSError) as exc:
        raise LoadFmuError(f"{where}: modelDescription.xml unreadable: {exc}") from None
    return ""


def _variable(by_name: dict[str, Any], name: str, causality: str, role: str, where: str) -> Any:
    """The speed input or torque output: present, of that causality, a scalar Real / Float64."""
    var = by_name.get(name)
    if var is None:
        hint = f" (name it with --load-fmu-map {role}=NAME)" if name == role else ""
        raise LoadFmuError(f"{where}: no variable '{name}' for the {role} {causality}{hint}")
    if var.causality != causality:
        raise LoadFmuError(f"{where}: variable '{name}' ({role}) has causality '{var.causality}', needs '{causality}'")
    if var.type not in _REAL_TYPES or var.dimensions:
        raise LoadFmuError(f"{where}: variable '{name}' ({role}) is {var.type}{'[]' if var.dimensions else ''}, "
                           "needs a scalar Real (FMI 2) / Float64 (FMI 3)")
    return var


def _param(by_name: dict[str, Any], name: str, value: float, where: str) -> LoadFmuParam:
    """A --load-fmu-set target: a scalar parameter (fixed or tunable) of a kind the loop can write."""
    var = by_name.get(name)
    option = f"{where}: --load-fmu-set {name}"
    if var is None:
        known = sorted(v.name for v in by_name.values() if v.causality == "parameter")
        raise LoadFmuError(f"{option}: no such variable (parameters: {', '.join(known) or 'none'})")
    if var.causality != "parameter" or var.variability not in ("fixed", "tunable"):
        raise LoadFmuError(f"{option}: causality '{var.causality}', variability '{var.variability}' (only fixed "
                           "or tunable parameters can be set)")
    kind = _KINDS.get(str(var.type))
    if kind is None or var.dimensions:
        raise LoadFmuError(f"{option}: type {var.type} (Real/Float64, Integer/Int32 or Boolean can be set)")
    if kind != REAL and not math.isfinite(value):
        raise LoadFmuError(f"{option}: an {'Integer' if kind == INTEGER else 'Boolean'} parameter, got {value:g}")
    if kind == INTEGER and (value != int(value) or not INT32_MIN <= value <= INT32_MAX):
        raise LoadFmuError(f"{option}: an Integer parameter (int32: {INT32_MIN} to {INT32_MAX}), got {value:g}")
    if kind == BOOLEAN and value not in (0.0, 1.0):
        raise LoadFmuError(f"{option}: a Boolean parameter (true/false, 1/0), got {value:g}")
    return LoadFmuParam(name, int(var.valueReference), kind, value)
