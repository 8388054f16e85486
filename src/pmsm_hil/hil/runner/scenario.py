"""Scenarios: operating point, reference and load profiles, settling time and metrics window."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from pathlib import Path
from typing import Any

from pmsm_hil.hil.errors import InputFileError, ParameterError
from pmsm_hil.hil.mechanics import DynoMechanics, InertiaMechanics, LoadProfile, Mechanics, TwoMassMechanics
from pmsm_hil.hil.resources import bundled_names, load_toml

_PACKAGE = "pmsm_hil.hil.scenarios"
#: default tolerance of the setpoint verdict `setpoint_held` [% of the reference]
#: (src/pmsm_hil/hil/runner/setpoint_hold.py)
DEFAULT_HOLD_TOLERANCE_PCT = 2.0
#: the fields of a scenario that may stand for the motor's ratings (`at_rated = true` in a scenario file)
RATED_FIELDS = ("speed_rpm", "load_nm")
#: the shaft between the motor and its load (inertia mechanics): one rigid mass, or two masses on an elastic shaft
SHAFTS = ("rigid", "two-mass")


@dataclass(frozen=True, slots=True)
class Scenario:
    """A closed-loop test. Times [s] count from the run start; the metrics window is
    [settle_s, settle_s + duration_s). Speeds in rpm, torques in N·m.

    mechanics: "inertia" (J, B, load profile) or "dyno" (speed held at the reference profile). shaft (inertia
    only): "rigid" (one mass, the motor's J) or "two-mass": the motor's J and a load mass load_inertia_kgm2 [kg·m²]
    on a shaft of shaft_stiffness_nm_per_rad [N·m/rad] and shaft_damping_nms_per_rad [N·m·s/rad], the load torque
    on the load mass (src/pmsm_hil/hil/mechanics.py TwoMassMechanics).
    speed_rpm / load_nm: final speed reference and load; initial_* (default: the final value) apply
    before speed_step_s / load_step_s. preset_integrator: start the speed PI integrator at the
    initial load (bumpless start at the operating point). load_steps: further (time [s], N·m) load
    steps after the first, in time order (e.g. 0 → 4 → 2 N·m: load_step_s/load_nm = the 4 N·m step,
    load_steps = ((t2, 2.0),)); the load after the last step is the last step's torque. theta0_rad:
    initial electrical rotor angle [rad]. hold_tolerance_pct: tolerance of the setpoint verdict `setpoint_held`
    [% of the reference] (`--hold-tolerance` wins). rated: the fields among speed_rpm and load_nm that stand for
    the motor's rated speed and torque (a file's `at_rated = true`: both; the file's values stand for a motor that
    states none); `RunConfig` resolves them for its motor (`for_motor`), an override (`with_overrides`) takes its
    field out.
    """

    name: str
    mechanics: str = "inertia"
    speed_rpm: float = 1500.0
    load_nm: float = 0.0
    initial_speed_rpm: float | None = None
    initial_load_nm: float | None = None
    speed_step_s: float | None = None
    load_step_s: float | None = None
    settle_s: float = 0.2
    duration_s: float = 0.2
    preset_integrator: bool = True
    description: str = ""
    load_steps: tuple[tuple[float, float], ...] = ()
    theta0_rad: float = 0.0
    hold_tolerance_pct: float = DEFAULT_HOLD_TOLERANCE_PCT
    rated: tuple[str, ...] = ()
    shaft: str = "rigid"
    load_inertia_kgm2: float | None = None
    shaft_stiffness_nm_per_rad: float | None = None
    shaft_damping_nms_per_rad: float = 0.0

    def __post_init__(self) -> None:
        if self.mechanics not in ("inertia", "dyno"):
            raise ParameterError(
                f"scenario '{self.name}': mechanics must be 'inertia' or 'dyno', got {self.mechanics!r}")
        self._check_shaft()
        for name in ("speed_rpm", "load_nm", "settle_s", "duration_s"):
            if not math.isfinite(getattr(self, name)):
                raise ParameterError(f"scenario '{self.name}': {name} must be finite")
        if self.duration_s <= 0:
            raise ParameterError(f"scenario '{self.name}': duration must be > 0 s, got {self.duration_s}")
        if self.settle_s < 0:
            raise ParameterError(f"scenario '{self.name}': settle_s must be ≥ 0 s, got {self.settle_s}")
        if not (math.isfinite(self.hold_tolerance_pct) and self.hold_tolerance_pct > 0.0):
            raise ParameterError(f"scenario '{self.name}': hold_tolerance_pct must be a finite number > 0 (% of the "
                                 f"reference), got {self.hold_tolerance_pct}")
        if not math.isfinite(self.theta0_rad):
            raise ParameterError(f"scenario '{self.name}': theta0_rad must be finite")
        if not set(self.rated) <= set(RATED_FIELDS):
            raise ParameterError(f"scenario '{self.name}': rated names fields of {', '.join(RATED_FIELDS)}, "
                                 f"got {self.rated!r}")
        last = self.load_step_s if self.load_step_s is not None else -math.inf
        for t, nm in self.load_steps:
            if not (math.isfinite(t) and math.isfinite(nm)):
                raise ParameterError(f"scenario '{self.name}': load_steps entries must be finite")
            if t <= last:
                raise ParameterError(
                    f"scenario '{self.name}': load_steps times must increase and follow load_step_s, got {t} s")
            last = t

    def _check_shaft(self) -> None:
        """The shaft's kind and, for two masses, its load inertia, stiffness and damping (ParameterError naming the
        field)."""
        if self.shaft not in SHAFTS:
            raise ParameterError(
                f"scenario '{self.name}': shaft must be one of {', '.join(SHAFTS)}, got {self.shaft!r}")
        for name in ("load_inertia_kgm2", "shaft_stiffness_nm_per_rad", "shaft_damping_nms_per_rad"):
            value = getattr(self, name)
            if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)
                                      or not math.isfinite(value)):
                raise ParameterError(f"scenario '{self.name}': {name} must be a finite number, got {value!r}")
        if self.shaft_damping_nms_per_rad < 0:
            raise ParameterError(f"scenario '{self.name}': shaft_damping_nms_per_rad must be ≥ 0 N·m·s/rad, got "
                                 f"{self.shaft_damping_nms_per_rad}")
        if self.shaft != "two-mass":
            return
        if self.mechanics != "inertia":
            raise ParameterError(f"scenario '{self.name}': shaft 'two-mass' needs mechanics 'inertia' (a dyno holds "
                                 "the motor's speed)")
        for name, unit, option in (("load_inertia_kgm2", "kg·m²", "--load-inertia"),
                                   ("shaft_stiffness_nm_per_rad", "N·m/rad", "--shaft-stiffness")):
            value = getattr(self, name)
            if value is None or value <= 0:
                raise ParameterError(f"scenario '{self.name}': shaft 'two-mass' needs {name} > 0 {unit} ({option}), "
                                     f"got {value}")

    def plant_mechanics(self, j_motor: float) -> Mechanics:
        """The plant's mechanics at the start: the dyno at the start speed, one mass with the load profile, or two
        masses (the motor's `j_motor` [kg·m²] and the load mass) on the shaft, untwisted at the start speed."""
        if self.mechanics == "dyno":
            return DynoMechanics(self.start_speed_rpm)
        if self.shaft == "two-mass":
            assert self.load_inertia_kgm2 is not None and self.shaft_stiffness_nm_per_rad is not None
            return TwoMassMechanics(self.load_profile(), j_motor=j_motor, j_load=self.load_inertia_kgm2,
                                    k_shaft=self.shaft_stiffness_nm_per_rad, c_shaft=self.shaft_damping_nms_per_rad,
                                    initial_speed_rpm=self.start_speed_rpm)
        return InertiaMechanics(self.load_profile(), initial_speed_rpm=self.start_speed_rpm)

    def driven_inertia_kgm2(self, j_motor: float) -> float:
        """The inertia the drive accelerates [kg·m²]: 0 under a dyno, the motor's `j_motor`, plus the load mass
        with a two-mass shaft."""
        if self.mechanics == "dyno":
            return 0.0
        if self.shaft == "two-mass" and self.load_inertia_kgm2 is not None:
            return j_motor + self.load_inertia_kgm2
        return j_motor

    @property
    def at_rated(self) -> bool:
        """Some of speed_rpm / load_nm stand for the motor's ratings until `for_motor` resolves them."""
        return bool(self.rated)

    @property
    def start_speed_rpm(self) -> float:
        """Speed at t = 0 [rpm]."""
        return self.speed_rpm if self.initial_speed_rpm is None else self.initial_speed_rpm

    @property
    def start_load_nm(self) -> float:
        """Load at t = 0 [N·m]."""
        return self.load_nm if self.initial_load_nm is None else self.initial_load_nm

    @property
    def total_s(self) -> float:
        """Settling plus metrics window [s]."""
        return self.settle_s + self.duration_s

    def speed_reference_rpm(self, t: float) -> float:
        """Speed reference [rpm] at time t [s]."""
        if self.speed_step_s is None or t >= self.speed_step_s:
            return self.speed_rpm
        return self.start_speed_rpm

    def load_profile(self) -> LoadProfile:
        """Load torque profile [N·m] over time [s]."""
        first = [] if self.load_step_s is None else [(self.load_step_s, self.load_nm)]
        if not first and not self.load_steps:
            return LoadProfile.constant(self.load_nm)
        return LoadProfile.steps(self.start_load_nm, [*first, *self.load_steps])

    def for_motor(self, rated_speed_rpm: float, rated_torque_nm: float) -> Scenario:
        """The copy with the `rated` fields at the motor's rated speed [rpm] and torque [N·m] (each where > 0, else
        the scenario's own value); a scenario without rated fields unchanged. `RunConfig` calls it for its motor
        (the one place that decides), so `hil run`, sweeps, the pytest plugin and a RunConfig built by hand get the
        same operating point."""
        if not self.rated:
            return self
        speed = rated_speed_rpm if "speed_rpm" in self.rated and rated_speed_rpm > 0 else self.speed_rpm
        load = rated_torque_nm if "load_nm" in self.rated and rated_torque_nm > 0 else self.load_nm
        return replace(self, speed_rpm=speed, load_nm=load, rated=())

    def with_overrides(self, **overrides: Any) -> Scenario:
        """Copy with CLI overrides (None values ignored); an overridden rated field is the motor's no longer."""
        clean = {k: v for k, v in overrides.items() if v is not None}
        rated = tuple(name for name in self.rated if name not in clean)
        return replace(self, **clean, rated=rated)


def scenario_names() -> list[str]:
    """Bundled scenario names."""
    return bundled_names(_PACKAGE)


def load_scenario(name_or_path: str) -> Scenario:
    """Load a bundled scenario by name or a TOML scenario file; errors name the key."""
    doc, origin = load_toml(name_or_path, _PACKAGE, file_label="scenario file", kind="scenario")
    known = ({f.name for f in fields(Scenario)} - {"rated"}) | {"at_rated"}
    unknown = set(doc) - known
    if unknown:
        raise InputFileError(f"scenario file {origin}: unknown key(s) {', '.join(sorted(unknown))}")
    for key, value in doc.items():
        if key in ("name", "mechanics", "description", "shaft"):
            if not isinstance(value, str):
                raise InputFileError(f"scenario file {origin}: '{key}' must be a string")
        elif key in ("preset_integrator", "at_rated"):
            if not isinstance(value, bool):
                raise InputFileError(f"scenario file {origin}: '{key}' must be true or false")
        elif key == "load_steps":
            doc[key] = _load_steps(value, origin)
        elif not isinstance(value, (int, float)) or isinstance(value, bool):
            raise InputFileError(f"scenario file {origin}: '{key}' must be a number")
    path = Path(name_or_path)
    doc.setdefault("name", path.stem if path.suffix else name_or_path)
    doc["rated"] = RATED_FIELDS if doc.pop("at_rated", False) else ()
    try:
        values: dict[str, Any] = {k: (float(v) if isinstance(v, int) and not isinstance(v, bool) else v)
                                  for k, v in doc.items()}
        return Scenario(**values)
    except ParameterError as exc:
        raise InputFileError(f"scenario file {origin}: {exc}") from None


def _load_steps(value: object, origin: str) -> tuple[tuple[float, float], ...]:
    """`load_steps = [[t_s, nm], ...]` from a scenario file."""
    bad = InputFileError(f"scenario file {origin}: 'load_steps' must be a list of [time_s, torque_nm] pairs")
    if not isinstance(value, list):
        raise bad
    out: list[tuple[float, float]] = []
    for item in value:
        if (not isinstance(item, list) or len(item) != 2
                or not all(isinstance(v, int | float) and not isinstance(v, bool) for v in item)):
            raise bad
        out.append((float(item[0]), float(item[1])))
    return tuple(out)
