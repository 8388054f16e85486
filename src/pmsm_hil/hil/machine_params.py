"""What every machine kind's parameter class offers the runner (one `…Params` class per kind, as
`pmsm_hil.hil.motor_params.PmsmParams`): the drive-level facts (DC link, mechanics, trips, speed PI: the bundled
kinds hold them in one `DriveParams`, src/pmsm_hil/hil/drive_params.py, and read them as their own attributes), the
`--set` overrides, and the machine's own model parameters the target is told (DBC ConfigParam ids).

Units: SI (V, A, kg·m², N·m·s/rad, s); speeds in rpm where named so.
"""

from __future__ import annotations

from typing import Any, ClassVar, Protocol, Self, runtime_checkable

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.protocol.ids import ParamId


@runtime_checkable
class MachineParams(Protocol):
    """The parameter class of a machine kind: a frozen dataclass validated at construction."""

    #: names `--set` accepts, with their units (for help texts)
    SETTABLE_UNITS: ClassVar[dict[str, str]]

    @classmethod
    def from_values(cls, values: dict[str, Any], name: str) -> Self:
        """The parameters of a preset's `[parameters]` table (numbers by name, SI); ParameterError naming a
        missing, unknown or invalid key."""

    @property
    def name(self) -> str:
        """Preset name or a label."""

    @property
    def pole_pairs(self) -> int:
        """Pole pairs (encoder resolution and electrical angle)."""

    @property
    def vdc(self) -> float:
        """DC-link voltage [V]."""

    @property
    def j(self) -> float:
        """Rotor + load inertia [kg·m²]."""

    @property
    def b(self) -> float:
        """Viscous friction [N·m·s/rad]."""

    @property
    def t_dead(self) -> float:
        """Inverter dead time per leg [s]."""

    @property
    def t_mpw(self) -> float:
        """Minimum gate pulse width [s]."""

    @property
    def i_trip(self) -> float:
        """Overcurrent trip on any phase current magnitude [A]."""

    @property
    def speed_trip_rpm(self) -> float:
        """Overspeed trip [rpm]."""

    @property
    def rated_speed_rpm(self) -> float:
        """Rated speed [rpm] (0: not stated)."""

    @property
    def rated_torque_nm(self) -> float:
        """Rated torque [N·m] as the preset states it (0: not stated; see `torque_rating_nm`)."""

    @property
    def speed_kp(self) -> float:
        """Speed-PI proportional gain [N·m/(rad/s)] written to the target by default."""

    @property
    def speed_ki(self) -> float:
        """Speed-PI integral gain [N·m/rad] written to the target by default."""

    @property
    def torque_rating_nm(self) -> float:
        """Rated torque [N·m]: the preset's, or an estimate from the machine model (limits and scenarios)."""

    def with_overrides(self, overrides: dict[str, Any]) -> Self:
        """A copy with ``--set NAME=VALUE`` overrides (SI units); ParameterError naming an unknown name."""

    def model_parameters(self) -> dict[ParamId, float]:
        """The machine model the target is told before enabling (DBC ConfigParam id → value, SI)."""


def check_preset_keys(values: dict[str, Any], known: set[str], required: tuple[str, ...], kind: str = "") -> None:
    """ParameterError naming the keys of a preset's `[parameters]` a kind's class does not know, then the required
    ones missing (`kind`: how the message names the machine, e.g. "induction-machine ")."""
    unknown = set(values) - known
    if unknown:
        raise ParameterError(f"unknown {kind}parameter(s) {', '.join(sorted(unknown))}")
    missing = set(required) - set(values)
    if missing:
        raise ParameterError(f"missing {kind}parameter(s) {', '.join(sorted(missing))}")


__all__ = ["MachineParams", "check_preset_keys"]
