"""The machine descriptor: everything that differs between machine kinds, asked in one place.

A `Machine` is made from a motor preset (`machine_for(params)` or `load_machine(name)`) and owns the phase
count, the parameters, the plant class, the measurement frame, the trace and record layouts and the
replay CSV columns. Code that would branch on "three or six phases" asks the descriptor instead; a new
machine kind is one `MachineLayout` entry (see docs/recipes.md, "A new machine kind").
Units are SI: currents A, angle rad (electrical), speed rad/s (mechanical), voltage V, time s.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Final

import numpy as np

from pmsm_hil.hil.errors import ParameterError
from pmsm_hil.hil.machine_params import MachineParams
from pmsm_hil.hil.mechanics import Mechanics
from pmsm_hil.hil.motor_params import PmsmParams
from pmsm_hil.hil.plant import Plant
from pmsm_hil.hil.plant6 import Plant6
from pmsm_hil.hil.plant_base import PlantBase
from pmsm_hil.hil.sensors import SensorModel
from pmsm_hil.protocol import codec6
from pmsm_hil.protocol.codec import L_MEAS_A, L_MEAS_B
from pmsm_hil.protocol.ids import ParamId
from pmsm_hil.protocol.layout import FrameLayout
from pmsm_hil.protocol.messages import Measurement, Measurement6

_NAN = math.nan
#: The six-phase record fields (i_u, i_v, i_w, i_x, i_y) of a machine without a second set: NaN.
NO_SECOND_SET: Final = (_NAN, _NAN, _NAN, _NAN, _NAN)

#: (seq, plant sample, sensor model, ideal sensors, vdc [V]) -> (frame to send, the record's
#: (i_u, i_v, i_w, i_x, i_y) [A] true values)
MeasureFn = Callable[[int, Any, SensorModel, bool, float], "tuple[Measurement | Measurement6, tuple[float, ...]]"]


def _measure3(seq: int, smp: Any, sensors: SensorModel, ideal: bool, vdc: float
              ) -> tuple[Measurement, tuple[float, ...]]:
    """Three-phase measurement frame of a `Plant` sample (sensor model applied unless ideal)."""
    if ideal:
        ia, ib, ic, th = smp.i_a, smp.i_b, smp.i_c, smp.theta_e
    else:
        ia, ib, ic = sensors.currents(smp.i_a, smp.i_b, smp.i_c)
        th = sensors.angle(smp.theta_e)
    return Measurement(seq=seq, i_a=ia, i_b=ib, i_c=ic, theta_e=th, omega_m=smp.omega_m, vdc=vdc), NO_SECOND_SET


def _measure6(seq: int, smp: Any, sensors: SensorModel, ideal: bool, vdc: float
              ) -> tuple[Measurement6, tuple[float, ...]]:
    """Six-phase measurement frame of a `Plant6` sample (sensor model applied per set of three)."""
    ia, ib, ic, iu, iv, iw = smp.phase_currents
    th = smp.theta_e
    if not ideal:
        ia, ib, ic = sensors.currents(ia, ib, ic)
        iu, iv, iw = sensors.currents(iu, iv, iw)
        th = sensors.angle(th)
    meas = Measurement6(seq=seq, i_a=ia, i_b=ib, i_c=ic, i_u=iu, i_v=iv, i_w=iw, theta_e=th,
                        omega_m=smp.omega_m, vdc=vdc)
    return meas, (smp.i_u, smp.i_v, smp.i_w, smp.i_x, smp.i_y)


@dataclass(frozen=True, slots=True)
class MeasurementFrames:
    """The Measurement frames a machine kind is measured with: `native` names the native loop's encoder
    (`NL_MEAS_*` of src/pmsm_hil/hil/runner/c/loop.h), `currents` the phase currents they carry; `current_layout` /
    `state_layout`: the DBC layouts whose signals give the current and angle/speed/vdc scales and raw limits."""

    native: str
    currents: int
    current_layout: FrameLayout
    state_layout: FrameLayout


MEAS_THREE: Final = MeasurementFrames("NL_MEAS_3", 3, L_MEAS_A, L_MEAS_B)
MEAS_SIX: Final = MeasurementFrames("NL_MEAS_6", 6, codec6.L_MEAS6_A, codec6.L_MEAS6_B)


def _no_extras(params: Any, rated_nm: float) -> dict[ParamId, float]:
    return {}


def _extras6(params: PmsmParams, rated_nm: float) -> dict[ParamId, float]:
    """The leakage inductance L_ls [H], and mptc3's torque hysteresis band B_T (not given by the paper):
    5 % of rated torque [N·m]; the firmware's 0.2 N·m default lets its torque-only cost drift i_d until it
    trips (docs/comparisons/zhang2021.md)."""
    return {ParamId.LLS: params.lls, ParamId.TORQUE_BAND: 0.05 * rated_nm}


def _replay_row3(s: Any) -> tuple[float, ...]:
    return (s.t, s.i_a, s.i_b, s.i_c, s.i_d, s.i_q, s.torque, s.theta_e, s.omega_m)


def _replay_row6(q: Any) -> tuple[float, ...]:
    return (q.t, q.i_a, q.i_b, q.i_c, q.i_u, q.i_v, q.i_w, q.i_d, q.i_q, q.i_x, q.i_y, q.torque, q.theta_e,
            q.omega_m)


@dataclass(frozen=True, slots=True)
class MachineLayout:
    """Facts of one machine kind: legs, plant class, frame builder and the record/CSV layouts.

    `legs`, `max_state_code` and `trace_dtype` come from the plant class. `params_class`: the kind's parameter
    class (`MachineParams`), and `accepts(params)` whether this layout runs a given instance of it (the PMSM
    layouts share `PmsmParams`: lls > 0 selects the dual three-phase one); `measurement`: the Measurement
    frames; `replay_legs` / `replay_columns`: CSV columns of `hil plant replay` input (one gate bit per leg) and
    output; `replay_row`: a plant sample → output row; `target_extras(params, rated torque [N·m])`: the
    machine-specific parameters written to the target before enabling, beyond `params.model_parameters()`.
    """

    kind: str
    plant_class: type[PlantBase]
    params_class: type
    accepts: Callable[[Any], bool]
    measurement: MeasurementFrames
    measure: MeasureFn
    replay_legs: tuple[str, ...]
    replay_columns: tuple[str, ...]
    replay_row: Callable[[Any], tuple[float, ...]]
    target_extras: Callable[[Any, float], dict[ParamId, float]]

    @property
    def legs(self) -> int:
        """Inverter legs = phases (the plant class's `LEGS`)."""
        return self.plant_class.LEGS

    @property
    def max_state_code(self) -> int:
        """Largest switching state code (the plant class's `MAX_STATE`)."""
        return self.plant_class.MAX_STATE

    @property
    def trace_dtype(self) -> np.dtype:
        """Record dtype of the plant's trace rows (all float64, the plant class's `TRACE_COLUMNS`)."""
        return np.dtype([(name, "f8") for name in self.plant_class.TRACE_COLUMNS])

    @property
    def trace_columns(self) -> int:
        """Doubles per trace row."""
        return len(self.trace_dtype.names or ())

    @property
    def native_kernel(self) -> str | None:
        """The name of the plant's machine-kernel table for the native loop (None: the Python loop only)."""
        return self.plant_class.KERNEL_TABLE


THREE_PHASE: Final = MachineLayout(
    kind="three-phase", plant_class=Plant, params_class=PmsmParams, accepts=lambda p: p.lls == 0.0,
    measurement=MEAS_THREE, measure=_measure3,
    replay_legs=("sa", "sb", "sc"),
    replay_columns=("t", "i_a", "i_b", "i_c", "i_d", "i_q", "torque", "theta_e", "omega_m"),
    replay_row=_replay_row3, target_extras=_no_extras)

DUAL_THREE_PHASE: Final = MachineLayout(
    kind="dual-three-phase", plant_class=Plant6, params_class=PmsmParams, accepts=lambda p: p.lls > 0.0,
    measurement=MEAS_SIX, measure=_measure6,
    replay_legs=("sa1", "sb1", "sc1", "sa2", "sb2", "sc2"),
    replay_columns=("t", "i_a1", "i_b1", "i_c1", "i_a2", "i_b2", "i_c2", "i_d", "i_q", "i_x", "i_y", "torque",
                    "theta_e", "omega_m"),
    replay_row=_replay_row6, target_extras=_extras6)

#: Machine layouts by kind, in registration order (the registry: a new kind is one `register_layout` call).
LAYOUTS: Final[dict[str, MachineLayout]] = {}


def register_layout(layout: MachineLayout) -> MachineLayout:
    """Add a machine kind to the registry (ParameterError if the kind is taken by another layout)."""
    held = LAYOUTS.get(layout.kind)
    if held is not None and held is not layout:
        raise ParameterError(f"machine kind {layout.kind!r} is already registered")
    LAYOUTS[layout.kind] = layout
    return layout


def unregister_layout(kind: str) -> None:
    """Remove a machine kind (tests that register their own)."""
    LAYOUTS.pop(kind, None)


register_layout(THREE_PHASE)
register_layout(DUAL_THREE_PHASE)
from pmsm_hil.hil import im_plant as _im_plant  # noqa: E402,F401  the induction machine kind "im" registers itself


def _register_fluxmap() -> None:
    """The saturated PMSM of a flux map (kind "pmsm-fluxmap": src/pmsm_hil/hil/fluxmap_plant.py, docs/plant.md)."""
    from pmsm_hil.hil.fluxmap_params import KIND, FluxMapParams
    from pmsm_hil.hil.fluxmap_plant import FluxMapPlant

    register_layout(MachineLayout(
        kind=KIND, plant_class=FluxMapPlant, params_class=FluxMapParams, accepts=lambda p: True,
        measurement=MEAS_THREE, measure=_measure3, replay_legs=THREE_PHASE.replay_legs,
        replay_columns=THREE_PHASE.replay_columns, replay_row=_replay_row3, target_extras=_no_extras))


_register_fluxmap()


def params_class_for_kind(kind: str) -> Any:
    """The parameter class of a registered machine kind (a preset's `kind`); ParameterError naming `kind` and
    the known kinds."""
    try:
        return LAYOUTS[kind].params_class
    except KeyError:
        raise ParameterError(f"kind: no machine kind {kind!r} (known: {', '.join(LAYOUTS)})") from None


def layout_for_phases(phases: int) -> MachineLayout:
    """The first registered layout of a phase count (the PMSM layouts for 3 and 6); ParameterError naming
    `phases` for a count no layout has."""
    for lay in LAYOUTS.values():
        if isinstance(phases, int) and lay.legs == phases:
            return lay
    known = ", ".join(str(k) for k in sorted({lay.legs for lay in LAYOUTS.values()}))
    raise ParameterError(f"phases: no machine layout for {phases!r} phases (known: {known})")


def layout_for_trace(names: tuple[str, ...]) -> MachineLayout | None:
    """The layout whose trace has exactly these field names (None if none does)."""
    return next((lay for lay in LAYOUTS.values() if tuple(lay.trace_dtype.names or ()) == names), None)


@dataclass(frozen=True, slots=True)
class Machine:
    """One motor preset with its machine kind: parameters plus the layout the run, logger, replay,
    metrics and dashboards use."""

    params: MachineParams
    layout: MachineLayout

    @property
    def name(self) -> str:
        """Preset name."""
        return self.params.name

    @property
    def phases(self) -> int:
        """Phase count = inverter legs (3 or 6)."""
        return self.layout.legs

    def build_plant(self, ts_s: float, mechanics: Mechanics, *, trace_dt_s: float | None = 2e-6,
                    theta0_rad: float = 0.0) -> PlantBase:
        """The exact plant of this machine, control period `ts_s` [s], trace step `trace_dt_s` [s] or None."""
        return self.layout.plant_class(self.params, ts_s, mechanics, trace_dt_s=trace_dt_s, theta0_rad=theta0_rad)


def machine_for(params: MachineParams) -> Machine:
    """The descriptor of a motor: the first registered layout of its parameter class that accepts it (a PMSM:
    six phases when it has a leakage inductance lls > 0, else three); ParameterError for a parameter class no
    registered kind has."""
    for lay in LAYOUTS.values():
        if isinstance(params, lay.params_class) and lay.accepts(params):
            return Machine(params, lay)
    raise ParameterError(f"motor '{params.name}': no registered machine kind takes {type(params).__name__} "
                         f"(known kinds: {', '.join(LAYOUTS)})")


def load_machine(name_or_path: str, overrides: dict[str, float] | None = None) -> Machine:
    """The descriptor of a bundled preset or a TOML file, with ``--set`` overrides (SI units)."""
    from pmsm_hil.hil.presets_loader import load_motor

    return machine_for(load_motor(name_or_path, overrides))


__all__ = ["DUAL_THREE_PHASE", "LAYOUTS", "MEAS_SIX", "MEAS_THREE", "NO_SECOND_SET", "THREE_PHASE", "Machine",
           "MachineLayout", "MeasurementFrames", "layout_for_phases", "layout_for_trace", "load_machine",
           "machine_for", "params_class_for_kind", "register_layout", "unregister_layout"]
