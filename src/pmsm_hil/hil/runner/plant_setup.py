"""The plant of a run at its scenario's starting point (mechanics from the scenario, class from the machine)."""

from __future__ import annotations

from pmsm_hil.hil.mechanics import DynoMechanics, InertiaMechanics
from pmsm_hil.hil.plant_base import PlantBase
from pmsm_hil.hil.runner.run_config import RunConfig


def build_plant(cfg: RunConfig) -> PlantBase:
    """Plant of `cfg.machine` with the scenario's mechanics (dyno speed or inertia with its load profile),
    start speed [rpm] and initial rotor angle [rad]."""
    sc = cfg.scenario
    if sc.mechanics == "dyno":
        mech: DynoMechanics | InertiaMechanics = DynoMechanics(sc.start_speed_rpm)
    else:
        mech = InertiaMechanics(sc.load_profile(), initial_speed_rpm=sc.start_speed_rpm)
    return cfg.machine.build_plant(cfg.ts_s, mech, trace_dt_s=cfg.trace_dt_s, theta0_rad=sc.theta0_rad)


__all__ = ["build_plant"]
