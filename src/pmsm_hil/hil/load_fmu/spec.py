"""What `--load-fmu PATH.fmu`, `--load-fmu-map` and `--load-fmu-set` ask for: parsed, not yet read."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.motor_params import parse_set_options

#: the FMU's variables the loop connects, by role: the speed input (mechanical rad/s) and the torque output (N·m)
ROLES = ("speed", "torque")
#: where the FMU runs (`--load-fmu-isolation`): its own process (contained), or the run's (unprotected)
ISOLATIONS = ("process", "none")


@dataclass(frozen=True, slots=True)
class LoadFmuSpec:
    """An FMU load: the .fmu file, the names of its speed input [rad/s] and torque output [N·m], and parameter
    values to set before initialisation (name, value; units the FMU's own), and where it runs (ISOLATIONS)."""

    path: Path
    speed: str = "speed"
    torque: str = "torque"
    params: tuple[tuple[str, float], ...] = ()
    isolation: str = "process"

    def as_dict(self) -> dict[str, object]:
        """The options as metrics.json says them."""
        return {"path": str(self.path), "speed": self.speed, "torque": self.torque, "parameters": dict(self.params),
                "isolation": self.isolation}


def parse_map(text: str | None) -> dict[str, str]:
    """`--load-fmu-map speed=w_shaft,torque=T_load`: role → FMU variable name (roles not given keep theirs)."""
    names = {role: role for role in ROLES}
    if not text:
        return names
    for item in text.split(","):
        role, sep, name = item.partition("=")
        role, name = role.strip(), name.strip()
        if not sep or not name:
            raise ParameterError(f"--load-fmu-map expects ROLE=NAME[,ROLE=NAME] with ROLE in {', '.join(ROLES)}, "
                                 f"got {item.strip()!r}")
        if role not in ROLES:
            raise ParameterError(f"--load-fmu-map: unknown role {role!r} (roles: {', '.join(ROLES)})")
        names[role] = name
    return names


def parse_sets(items: list[str] | None) -> tuple[tuple[str, float], ...]:
    """`--load-fmu-set NAME=VALUE` items (repeatable): numbers (as `--set`), or true/false for a Boolean."""
    flags: dict[str, float] = {}
    numbers: list[str] = []
    for item in items or []:
        name, sep, text = item.partition("=")
        if sep and name.strip() and text.strip().lower() in ("true", "false"):
            flags[name.strip()] = 1.0 if text.strip().lower() == "true" else 0.0
        else:
            numbers.append(item)
    try:
        values = parse_set_options(numbers)
    except ParameterError as exc:
        raise ParameterError(str(exc).replace("--set", "--load-fmu-set", 1)) from None
    return tuple({**values, **flags}.items())


def load_fmu_spec(path: str | Path | None, mapping: str | None, sets: list[str] | None, *,
                  isolation: str | None = None) -> LoadFmuSpec | None:
    """The spec of the options (None without --load-fmu; --load-fmu-map/--load-fmu-set alone are an error)."""
    if path is None or str(path) == "":
        if mapping or sets:
            option = "--load-fmu-map" if mapping else "--load-fmu-set"
            raise ParameterError(f"{option}: only with --load-fmu PATH.fmu")
        return None
    names = parse_map(mapping)
    where = isolation or "process"
    if where not in ISOLATIONS:
        raise ParameterError(f"--load-fmu-isolation must be one of {', '.join(ISOLATIONS)}, got {where!r}")
    return LoadFmuSpec(Path(path), speed=names["speed"], torque=names["torque"], params=parse_sets(sets),
                       isolation=where)
