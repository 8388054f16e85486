"""Typed, validated parameters of a squirrel-cage induction machine (inverse-Γ model) and its two-level inverter.

The model (as motulator's `InductionMachineInvGammaPars`): stator resistance Rs, rotor resistance RR, leakage
inductance Lσ and magnetizing inductance LM of the inverse-Γ equivalent circuit, n_p pole pairs; see
docs/plant.md ("Induction machine"). Units: SI (Ω, H, Wb, V, A, kg·m², N·m·s/rad, s); speeds in rpm where named so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

from pmsm_hil.hil.drive_params import DriveParams, WithDrive
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.machine_params import check_preset_keys
from pmsm_hil.protocol.ids import ParamId

#: Names `--set NAME=VALUE` accepts for an induction machine, with their units.
IM_SETTABLE_UNITS: dict[str, str] = {
    "rs": "Ω", "rr": "Ω", "lsigma": "H", "lm": "H", "psi_r_ref": "Wb", "pole_pairs": "", "vdc": "V",
    "j": "kg·m²", "b": "N·m·s/rad", "t_dead": "s", "t_mpw": "s", "i_trip": "A", "speed_trip_rpm": "rpm",
    "speed_kp": "N·m/(rad/s)", "speed_ki": "N·m/rad", "current_bandwidth_hz": "Hz",
}


@dataclass(frozen=True, slots=True)
class ImParams(WithDrive):
    """Squirrel-cage induction machine, inverse-Γ equivalent circuit, on a two-level inverter.

    Attributes:
        rs: stator resistance [Ω], > 0.
        rr: rotor resistance of the inverse-Γ model [Ω], > 0.
        lsigma: leakage inductance Lσ [H], > 0.
        lm: magnetizing inductance LM [H], > 0.
        pole_pairs: n_p, integer ≥ 1.
        drive: the drive around the machine (DriveParams: vdc, j, b, t_dead, t_mpw, trips, rated figures, speed
            PI; an induction machine's trips default to 15 A and 3000 rpm), its fields also read as attributes of
            this class (`params.j`).
        psi_r_ref: the nominal rotor-flux reference the controller is told [Wb], > 0 (im-foc lowers it above base
            speed: field weakening).
        current_bandwidth_hz: the current-loop bandwidth the controller's PI gains are set for [Hz], > 0.
        name: preset name or a label.

    Build one from flat values with `ImParams.build(rs=..., rr=..., ..., vdc=..., j=...)`.
    """

    rs: float
    rr: float
    lsigma: float
    lm: float
    pole_pairs: int
    drive: DriveParams
    psi_r_ref: float = 0.9
    current_bandwidth_hz: float = 500.0
    name: str = "custom-im"

    DRIVE_DEFAULTS: ClassVar[dict[str, float]] = {"i_trip": 15.0, "speed_trip_rpm": 3000.0}

    SETTABLE_UNITS: ClassVar[dict[str, str]] = IM_SETTABLE_UNITS
    #: keys a preset must give
    REQUIRED: ClassVar[tuple[str, ...]] = ("rs", "rr", "lsigma", "lm", "pole_pairs", "vdc", "j")

    @classmethod
    def from_values(cls, values: dict[str, Any], name: str) -> ImParams:
        """From a preset's `[parameters]` (kind = "im"); ParameterError naming a missing, unknown or invalid key."""
        check_preset_keys(values, cls.parameter_names(), cls.REQUIRED, "induction-machine ")
        return cls.build(name=name, **_clean(values))

    def __post_init__(self) -> None:
        positive = ("rs", "rr", "lsigma", "lm", "psi_r_ref", "current_bandwidth_hz")
        for key in positive:
            value = getattr(self, key)
            if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
                raise ParameterError(f"induction-machine parameter '{key}' must be a finite number, got {value!r}")
            if value <= 0:
                raise ParameterError(f"induction-machine parameter '{key}' must be > 0 "
                                     f"{IM_SETTABLE_UNITS.get(key, '')}, got {value}")
        if isinstance(self.pole_pairs, bool) or not isinstance(self.pole_pairs, int) or self.pole_pairs < 1:
            raise ParameterError(f"induction-machine parameter 'pole_pairs' must be an integer ≥ 1, "
                                 f"got {self.pole_pairs!r}")

    def with_overrides(self, overrides: dict[str, Any]) -> ImParams:
        """A copy with `--set` overrides (SI units); ParameterError naming an unknown or invalid name."""
        known = self.parameter_names()
        unknown = set(overrides) - known
        if unknown:
            raise ParameterError(f"unknown induction-machine parameter '{sorted(unknown)[0]}' "
                                 f"(known: {', '.join(sorted(known))})")
        return self.with_values(**_clean(overrides))

    @property
    def torque_rating_nm(self) -> float:
        """Rated torque [N·m]: the preset's, else 1.5·n_p·ψR_ref·iq at the torque current that with the flux
        current ψR_ref/LM makes half the trip current."""
        if self.rated_torque_nm > 0:
            return self.rated_torque_nm
        i_d = self.psi_r_ref / self.lm
        i_q = math.sqrt(max((0.5 * self.i_trip) ** 2 - i_d * i_d, 0.0))
        return 1.5 * self.pole_pairs * self.psi_r_ref * i_q

    def model_parameters(self) -> dict[ParamId, float]:
        """The machine model the target is told: Rs, RR [Ω], Lσ, LM [H], the rotor-flux reference ψR_ref [Wb],
        and the current-PI gains for `current_bandwidth_hz` on the stator transient circuit (kp = α·Lσ [V/A],
        ki = α·(Rs + RR) [V/(A·s)], α = 2π·bandwidth)."""
        alpha = 2.0 * math.pi * self.current_bandwidth_hz
        return {ParamId.RS: self.rs, ParamId.RR: self.rr, ParamId.LSIGMA: self.lsigma, ParamId.LM: self.lm,
                ParamId.PSI_R_REF: self.psi_r_ref, ParamId.CURRENT_KP: alpha * self.lsigma,
                ParamId.CURRENT_KI: alpha * (self.rs + self.rr)}


def _clean(values: dict[str, Any]) -> dict[str, Any]:
    """Numbers by key, pole_pairs an integer (ParameterError naming it otherwise)."""
    clean: dict[str, Any] = {}
    for key, value in values.items():
        if key == "pole_pairs":
            if isinstance(value, bool) or not isinstance(value, int | float) or float(value) != int(value):
                raise ParameterError(f"induction-machine parameter 'pole_pairs' must be an integer, got {value!r}")
            clean[key] = int(value)
        else:
            clean[key] = float(value)
    return clean


__all__ = ["IM_SETTABLE_UNITS", "ImParams"]
