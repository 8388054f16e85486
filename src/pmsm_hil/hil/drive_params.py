"""The drive around a machine: what every machine kind's parameter class holds besides its own model.

`DriveParams` groups the converter (DC link, dead time, minimum pulse), the mechanics (inertia, friction), the
protection (trips), the rated figures and the speed PI the runner writes to the target. Each kind's parameter class
(`PmsmParams`, `ImParams`, `FluxMapParams`) contains one as its `drive` field and, through `WithDrive`, offers the
drive's fields as read-only attributes of its own: `params.j` is `params.drive.j`, so scripts, presets' keys and
`--set` names read as they always did. Build a kind's parameters from flat values with `Kind.build(...)`
(`PmsmParams.build(rs=..., vdc=..., j=...)`) and change any of them with `params.with_values(...)`.

Units: SI (V, s, kg·m², N·m·s/rad, A, N·m); speeds in rpm where named so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import Any, ClassVar, Self

from pmsm_hil.hil.errors import ParameterError

#: the drive's parameters with their units
DRIVE_UNITS: dict[str, str] = {
    "vdc": "V", "j": "kg·m²", "b": "N·m·s/rad", "t_dead": "s", "t_mpw": "s", "i_trip": "A", "speed_trip_rpm": "rpm",
    "rated_speed_rpm": "rpm", "rated_torque_nm": "N·m", "speed_kp": "N·m/(rad/s)", "speed_ki": "N·m/rad",
}
_POSITIVE = ("vdc", "j", "i_trip", "speed_trip_rpm")
_NON_NEGATIVE = ("b", "t_dead", "t_mpw", "rated_speed_rpm", "rated_torque_nm", "speed_kp", "speed_ki")


@dataclass(frozen=True, slots=True)
class DriveParams:
    """Converter, mechanics, protection and speed PI of a drive.

    Attributes:
        vdc: DC-link voltage [V], > 0.
        j: rotor + load inertia [kg·m²], > 0 (inertia mode).
        b: viscous friction [N·m·s/rad], ≥ 0.
        t_dead: inverter dead time per leg [s], ≥ 0 and < 1 ms.
        t_mpw: minimum gate pulse width [s], ≥ 0 and < 1 ms.
        i_trip: overcurrent trip on any phase current magnitude [A], > 0.
        speed_trip_rpm: overspeed trip [rpm], > 0.
        rated_speed_rpm, rated_torque_nm: rated figures [rpm], [N·m] (0: not stated).
        speed_kp, speed_ki: the outer speed-PI gains the runner writes to the target by default
            [N·m/(rad/s)], [N·m/rad], ≥ 0 (the defaults are the niu2020 paper's, tuned for J ≈ 1.3e-3 kg·m²).
    """

    vdc: float
    j: float
    b: float = 0.0
    t_dead: float = 0.0
    t_mpw: float = 0.0
    i_trip: float = 30.0
    speed_trip_rpm: float = 6000.0
    rated_speed_rpm: float = 0.0
    rated_torque_nm: float = 0.0
    speed_kp: float = 0.8
    speed_ki: float = 0.35

    def __post_init__(self) -> None:
        for name in _POSITIVE + _NON_NEGATIVE:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise ParameterError(f"motor parameter '{name}' must be a finite number, got {value!r}")
            if name in _POSITIVE and value <= 0:
                raise ParameterError(f"motor parameter '{name}' must be > 0 {DRIVE_UNITS[name]}, got {value}")
            if name in _NON_NEGATIVE and value < 0:
                raise ParameterError(f"motor parameter '{name}' must be ≥ 0, got {value}")
        if self.t_dead > 1e-3 or self.t_mpw > 1e-3:
            raise ParameterError("motor parameters 't_dead'/'t_mpw' are in seconds and must be < 1 ms")


#: the drive's field names, in their order
DRIVE_FIELDS: tuple[str, ...] = tuple(f.name for f in fields(DriveParams))


class WithDrive:
    """A machine kind's parameter class (a frozen dataclass with a `drive: DriveParams` field): the drive's fields as
    its own read-only attributes, construction from flat values and copies with changed values."""

    __slots__ = ()
    drive: DriveParams
    #: the drive defaults of this kind where they differ from DriveParams' (e.g. an induction machine's trips)
    DRIVE_DEFAULTS: ClassVar[dict[str, float]] = {}

    @classmethod
    def build(cls, **values: Any) -> Self:
        """The parameters from flat values: the machine's own fields and the drive's (DRIVE_FIELDS) by name."""
        drive = {**cls.DRIVE_DEFAULTS, **{k: values.pop(k) for k in DRIVE_FIELDS if k in values}}
        try:
            made = DriveParams(**drive)
        except TypeError as exc:  # a required drive value missing
            raise ParameterError(f"motor parameters: {exc}") from None
        return cls(drive=made, **values)  # type: ignore[call-arg]  # the subclass dataclass's fields

    @classmethod
    def parameter_names(cls) -> set[str]:
        """Every parameter name a preset or `--set` may give: the machine's own fields and the drive's."""
        return {f.name for f in fields(cls)} - {"name", "drive"} | set(DRIVE_FIELDS)  # type: ignore[arg-type]

    def with_values(self, **changes: Any) -> Self:
        """A copy with the named parameters (the machine's own or the drive's) changed."""
        drive = {k: changes.pop(k) for k in DRIVE_FIELDS if k in changes}
        return replace(self, drive=replace(self.drive, **drive), **changes)  # type: ignore[type-var]

    @property
    def vdc(self) -> float:
        """DC-link voltage [V]."""
        return self.drive.vdc

    @property
    def j(self) -> float:
        """Rotor + load inertia [kg·m²]."""
        return self.drive.j

    @property
    def b(self) -> float:
        """Viscous friction [N·m·s/rad]."""
        return self.drive.b

    @property
    def t_dead(self) -> float:
        """Inverter dead time per leg [s]."""
        return self.drive.t_dead

    @property
    def t_mpw(self) -> float:
        """Minimum gate pulse width [s]."""
        return self.drive.t_mpw

    @property
    def i_trip(self) -> float:
        """Overcurrent trip on any phase current magnitude [A]."""
        return self.drive.i_trip

    @property
    def speed_trip_rpm(self) -> float:
        """Overspeed trip [rpm]."""
        return self.drive.speed_trip_rpm

    @property
    def rated_speed_rpm(self) -> float:
        """Rated speed [rpm] (0: not stated)."""
        return self.drive.rated_speed_rpm

    @property
    def rated_torque_nm(self) -> float:
        """Rated torque [N·m] as the preset states it (0: not stated)."""
        return self.drive.rated_torque_nm

    @property
    def speed_kp(self) -> float:
        """Speed-PI proportional gain [N·m/(rad/s)]."""
        return self.drive.speed_kp

    @property
    def speed_ki(self) -> float:
        """Speed-PI integral gain [N·m/rad]."""
        return self.drive.speed_ki


def flat_values(params: Any) -> dict[str, Any]:
    """Name → value of a machine's parameters (a dataclass instance), a `drive` field's values in its place."""
    out: dict[str, Any] = {}
    for f in fields(params):
        value = getattr(params, f.name)
        if isinstance(value, DriveParams):
            out.update({name: getattr(value, name) for name in DRIVE_FIELDS})
        else:
            out[f.name] = value
    return out


__all__ = ["DRIVE_FIELDS", "DRIVE_UNITS", "DriveParams", "WithDrive", "flat_values"]
