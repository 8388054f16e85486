"""Typed, validated parameters of a three-phase (or dual three-phase) PMSM and its two-level inverter."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

from pmsm_hil.hil.drive_params import DriveParams, WithDrive
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.machine_params import check_preset_keys
from pmsm_hil.protocol.ids import ParamId

#: Names accepted by ``--set NAME=VALUE`` on every command that takes a motor, with their units.
SETTABLE_UNITS: dict[str, str] = {
    "rs": "Ω",
    "ld": "H",
    "lq": "H",
    "psi_f": "Wb",
    "pole_pairs": "",
    "vdc": "V",
    "j": "kg·m²",
    "b": "N·m·s/rad",
    "t_dead": "s",
    "t_mpw": "s",
    "i_trip": "A",
    "speed_trip_rpm": "rpm",
    "lls": "H",
    "speed_kp": "N·m/(rad/s)",
    "speed_ki": "N·m/rad",
}


@dataclass(frozen=True, slots=True)
class PmsmParams(WithDrive):
    """Three-phase PMSM in the rotor dq frame (d on the magnet) fed by a two-level inverter.

    Attributes:
        rs: stator resistance per phase [Ω], > 0.
        ld: d-axis inductance [H], > 0.
        lq: q-axis inductance [H], > 0 (ld == lq: SPMSM).
        psi_f: permanent-magnet flux linkage [Wb], ≥ 0.
        pole_pairs: number of pole pairs, integer ≥ 1.
        drive: the drive around the machine (DriveParams: vdc, j, b, t_dead, t_mpw, trips, rated figures, speed
            PI), its fields also read as attributes of this class (`params.j`); the speed-PI gains belong with the
            inertia: a machine with another inertia than niu2020's states its own in its preset.
        name: preset name or a label.
        lls: leakage inductance of the x-y subspace of a dual three-phase machine [H], ≥ 0; 0 (the
            default) for a three-phase machine. `pmsm_hil.hil.plant6.Plant6` requires lls > 0.

    Build one from flat values with `PmsmParams.build(rs=..., ld=..., lq=..., psi_f=..., pole_pairs=..., vdc=...,
    j=...)`; change values with `with_values(...)`.
    """

    rs: float
    ld: float
    lq: float
    psi_f: float
    pole_pairs: int
    drive: DriveParams
    name: str = "custom"
    lls: float = 0.0

    SETTABLE_UNITS: ClassVar[dict[str, str]] = SETTABLE_UNITS
    #: keys a preset must give
    REQUIRED: ClassVar[tuple[str, ...]] = ("rs", "ld", "lq", "psi_f", "pole_pairs", "vdc", "j")

    @classmethod
    def from_values(cls, values: dict[str, Any], name: str) -> PmsmParams:
        """A PMSM from a preset's parameter values; ParameterError naming a missing, unknown or invalid key."""
        check_preset_keys(values, cls.parameter_names(), cls.REQUIRED)
        clean: dict[str, Any] = {}
        for key, value in values.items():
            if key == "pole_pairs":
                if float(value) != int(value):
                    raise ParameterError("'pole_pairs' must be an integer")
                clean[key] = int(value)
            else:
                clean[key] = float(value)
        return cls.build(name=name, **clean)

    def __post_init__(self) -> None:
        positive = ("rs", "ld", "lq")
        non_negative = ("psi_f", "lls")
        for name in positive + non_negative:
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value):
                raise ParameterError(f"motor parameter '{name}' must be a finite number, got {value!r}")
            if name in positive and value <= 0:
                raise ParameterError(
                    f"motor parameter '{name}' must be > 0 {SETTABLE_UNITS.get(name, '')}, got {value}"
                )
            if name in non_negative and value < 0:
                raise ParameterError(f"motor parameter '{name}' must be ≥ 0, got {value}")
        if isinstance(self.pole_pairs, bool) or not isinstance(self.pole_pairs, int) or self.pole_pairs < 1:
            raise ParameterError(f"motor parameter 'pole_pairs' must be an integer ≥ 1, got {self.pole_pairs!r}")

    @property
    def is_six_phase(self) -> bool:
        """True for a dual three-phase machine (lls > 0)."""
        return self.lls > 0.0

    @property
    def is_salient(self) -> bool:
        """True for an interior PMSM (Ld ≠ Lq)."""
        return self.ld != self.lq

    def with_overrides(self, overrides: dict[str, Any]) -> PmsmParams:
        """Return a copy with ``--set`` style overrides applied (values already parsed)."""
        valid = self.parameter_names()
        clean: dict[str, Any] = {}
        for key, value in overrides.items():
            if key not in valid:
                raise ParameterError(f"unknown motor parameter '{key}' (known: {', '.join(sorted(valid))})")
            clean[key] = int(value) if key == "pole_pairs" else float(value)
            if key == "pole_pairs" and float(value) != int(value):
                raise ParameterError(f"motor parameter 'pole_pairs' must be an integer, got {value!r}")
        return self.with_values(**clean)

    @property
    def torque_rating_nm(self) -> float:
        """Rated torque [N·m]: the preset's, else the magnet torque at half the trip current 1.5·p·ψf·i_trip/2."""
        if self.rated_torque_nm > 0:
            return self.rated_torque_nm
        return self.psi_f * 1.5 * self.pole_pairs * 0.5 * self.i_trip

    def model_parameters(self) -> dict[ParamId, float]:
        """The PMSM model the target is told: Rs [Ω], Ld, Lq [H], ψf [Wb] (the dual three-phase layout adds
        L_ls through its `target_extras`)."""
        return {ParamId.RS: self.rs, ParamId.LD: self.ld, ParamId.LQ: self.lq, ParamId.PSI_F: self.psi_f}

    def torque_nm(self, i_d: float, i_q: float) -> float:
        """Electromagnetic torque 1.5·p·(ψf·iq + (Ld−Lq)·id·iq) [N·m] for currents [A]."""
        return 1.5 * self.pole_pairs * (self.psi_f * i_q + (self.ld - self.lq) * i_d * i_q)


def parse_set_options(items: list[str] | None) -> dict[str, float]:
    """Parse ``NAME=VALUE`` strings into a dict; errors name the offending item."""
    result: dict[str, float] = {}
    for item in items or []:
        name, sep, text = item.partition("=")
        name = name.strip()
        if not sep or not name:
            raise ParameterError(f"--set expects NAME=VALUE, got {item!r}")
        try:
            value = float(text)
        except ValueError:
            raise ParameterError(f"--set {name}: value {text!r} is not a number") from None
        if not math.isfinite(value):
            raise ParameterError(f"--set {name}: value must be finite, got {text!r}")
        result[name] = value
    return result
