"""What differs between three-phase and dual three-phase runs: plant, measurement frame, records."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from pmsm_hil.hil.mechanics import DynoMechanics, InertiaMechanics
from pmsm_hil.hil.plant import Plant
from pmsm_hil.hil.plant6 import Plant6
from pmsm_hil.hil.plant_base import PlantBase
from pmsm_hil.hil.records import TRACE_DTYPE, TRACE_DTYPE6
from pmsm_hil.hil.runner.run_config import RunConfig
from pmsm_hil.hil.sensors import SensorModel
from pmsm_hil.protocol.messages import Measurement, Measurement6

_NAN = math.nan
#: Six-phase record fields (i_u, i_v, i_w, i_x, i_y) of a three-phase run.
NO_SIX_PHASE = (_NAN, _NAN, _NAN, _NAN, _NAN)


@dataclass(frozen=True, slots=True)
class PhaseSetup:
    """Legs of the inverter and the trace layout of the plant it drives."""

    legs: int
    trace_dtype: np.dtype

    @property
    def trace_columns(self) -> int:
        """Doubles per trace row."""
        return len(self.trace_dtype.names or ())


THREE_PHASE = PhaseSetup(3, TRACE_DTYPE)
SIX_PHASE = PhaseSetup(6, TRACE_DTYPE6)


def phase_setup(cfg: RunConfig) -> PhaseSetup:
    """Three- or six-phase, from the motor (six-phase motors have lls > 0)."""
    return SIX_PHASE if cfg.motor.is_six_phase else THREE_PHASE


def build_plant(cfg: RunConfig) -> PlantBase:
    """Plant at the scenario's starting point (Plant6 for a six-phase motor)."""
    sc = cfg.scenario
    if sc.mechanics == "dyno":
        mech: DynoMechanics | InertiaMechanics = DynoMechanics(sc.start_speed_rpm)
    else:
        mech = InertiaMechanics(sc.load_profile(), initial_speed_rpm=sc.start_speed_rpm)
    cls = Plant6 if cfg.motor.is_six_phase else Plant
    return cls(cfg.motor, cfg.ts_s, mech, trace_dt_s=cfg.trace_dt_s, theta0_rad=sc.theta0_rad)


def measurement6(seq: int, smp: Any, sensors: SensorModel, ideal: bool, vdc: float) -> Measurement6:
    """The six-phase measurement frame of a Plant6 sample (sensor model applied per set of three)."""
    ia, ib, ic, iu, iv, iw = smp.phase_currents
    th = smp.theta_e
    if not ideal:
        ia, ib, ic = sensors.currents(ia, ib, ic)
        iu, iv, iw = sensors.currents(iu, iv, iw)
        th = sensors.angle(th)
    return Measurement6(seq=seq, i_a=ia, i_b=ib, i_c=ic, i_u=iu, i_v=iv, i_w=iw, theta_e=th,
                        omega_m=smp.omega_m, vdc=vdc)


__all__ = ["NO_SIX_PHASE", "SIX_PHASE", "THREE_PHASE", "Measurement", "PhaseSetup", "build_plant",
           "measurement6", "phase_setup"]
