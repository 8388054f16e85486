"""A machine kind added the way docs/recipes.md says ("A new machine kind"): its C kernel (rl_load.c), its
parameter class and its plant class (this file), and one registry line (`register_rl_load`). Nothing else in the
package knows it: the test proves the C period loop runs it through its kernel table.

The machine: a balanced three-phase R-L load in star on the two-level inverter, no back-EMF, at a held speed
that only turns the dq view of its currents (rl_load.c). Units: SI.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from pmsm_hil.hil.cdef_extract import declarations
from pmsm_hil.hil.drive_params import DriveParams, WithDrive
from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.kernel_build import build_kernel_module
from pmsm_hil.hil.machine import MEAS_THREE, THREE_PHASE, MachineLayout, register_layout
from pmsm_hil.hil.plant import TRACE_COLUMNS, PlantSample
from pmsm_hil.hil.plant_base import ThreePhasePlant
from pmsm_hil.protocol.ids import ParamId

KERNEL_C = Path(__file__).with_name("rl_load.c")
#: what Python reads of the kernel, taken from its C file (no declaration typed twice)
CDEF = declarations(KERNEL_C, ["rl_params_t", "rl_state_t", "rl_period_stats_t", "rl_advance", "rl_sample",
                               "rl_kernel"])


@dataclass(frozen=True, slots=True)
class RlLoadParams(WithDrive):
    """R-L load: r [Ω], l [H] per phase, the flux `psi_model` [Wb] the controller is told (its torque-to-current
    scale: the load itself has none), and the drive facts every machine kind has (`drive`, DriveParams; read as
    attributes too). Build one from flat values with `RlLoadParams.build(r=..., l=..., vdc=...)`."""

    r: float
    l: float  # noqa: E741 - the inductance's own symbol
    drive: DriveParams
    psi_model: float = 0.1
    pole_pairs: int = 2
    name: str = "rl-load"

    DRIVE_DEFAULTS: ClassVar[dict[str, float]] = {"j": 1.0, "i_trip": 50.0}
    SETTABLE_UNITS: ClassVar[dict[str, str]] = {"r": "Ω", "l": "H", "vdc": "V", "psi_model": "Wb", "i_trip": "A"}

    @classmethod
    def from_values(cls, values: dict[str, Any], name: str) -> RlLoadParams:
        """From a preset's `[parameters]` (kind = "rl-load")."""
        _check_names(set(values), cls.parameter_names())
        missing = {"r", "l", "vdc"} - set(values)
        if missing:
            raise ParameterError(f"missing R-L load parameter(s) {', '.join(sorted(missing))}")
        return cls.build(name=name, **{k: int(v) if k == "pole_pairs" else float(v) for k, v in values.items()})

    def __post_init__(self) -> None:
        for key in ("r", "l", "psi_model"):
            value = getattr(self, key)
            if not (isinstance(value, float | int) and math.isfinite(value) and value > 0):
                raise ParameterError(f"R-L load parameter '{key}' must be a finite number > 0, got {value!r}")

    @property
    def torque_rating_nm(self) -> float:
        """The torque the controller would ask at half the trip current [N·m]."""
        return self.rated_torque_nm or 1.5 * self.pole_pairs * self.psi_model * 0.5 * self.i_trip

    def with_overrides(self, overrides: dict[str, Any]) -> RlLoadParams:
        """A copy with `--set` overrides."""
        _check_names(set(overrides), self.parameter_names())
        return self.with_values(**overrides)

    def model_parameters(self) -> dict[ParamId, float]:
        """The controller's model: a round-rotor machine of R, L and the flux psi_model, and FOC's current-PI
        gains for a 1 kHz loop bandwidth on this load (kp = 2π·1 kHz·L [V/A], ki = 2π·1 kHz·R [V/(A·s)])."""
        bandwidth = 2.0 * math.pi * 1000.0
        return {ParamId.RS: self.r, ParamId.LD: self.l, ParamId.LQ: self.l, ParamId.PSI_F: self.psi_model,
                ParamId.CURRENT_KP: bandwidth * self.l, ParamId.CURRENT_KI: bandwidth * self.r}


def _check_names(given: set[str], known: set[str]) -> None:
    unknown = given - known
    if unknown:
        raise ParameterError(f"unknown R-L load parameter(s) {', '.join(sorted(unknown))}")


class RlLoadPlant(ThreePhasePlant):
    """The R-L load through its C kernel (built by `register_rl_load`)."""

    NATIVE_MODULE: ClassVar[Any] = None
    KERNEL_TABLE = "rl_kernel"
    KERNEL_PREFIX = "rl"
    TRACE_COLUMNS = TRACE_COLUMNS

    def _kernel_advance(self, *args: Any) -> int:
        return int(self.NATIVE_MODULE.lib.rl_advance(*args))

    def _set_kernel_params(self, params: RlLoadParams) -> None:
        self._p.r, self._p.l, self._p.vdc, self._p.pole_pairs = params.r, params.l, params.vdc, params.pole_pairs
        self._out = self._ffi.new("mk_sample_t *")

    def sample(self) -> PlantSample:
        """The kernel's own sample (the same C function the native loop calls)."""
        o = self._out
        self.NATIVE_MODULE.lib.rl_sample(self._p, self._s, o)
        return PlantSample(int(self._s.t_ns) / 1e9, o.i[0], o.i[1], o.i[2], o.i_d, o.i_q, o.theta_e, o.omega_m,
                           o.torque, self._p.vdc)


RL_LOAD = MachineLayout(
    kind="rl-load", plant_class=RlLoadPlant, params_class=RlLoadParams, accepts=lambda p: True,
    measurement=MEAS_THREE, measure=THREE_PHASE.measure, replay_legs=THREE_PHASE.replay_legs,
    replay_columns=THREE_PHASE.replay_columns, replay_row=THREE_PHASE.replay_row, target_extras=lambda p, rated: {})


def register_rl_load(build_dir: Path) -> MachineLayout:
    """Build the kernel into `build_dir` and register the kind (the one registry line)."""
    RlLoadPlant.NATIVE_MODULE = build_kernel_module("rl_load_kernel", KERNEL_C, CDEF, build_dir)
    return register_layout(RL_LOAD)
