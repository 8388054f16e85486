"""The plant of a run at its scenario's starting point (mechanics from the scenario, class from the machine)."""

from __future__ import annotations

from pmsm_hil.hil.plant_base import PlantBase
from pmsm_hil.hil.runner.run_config import RunConfig


def build_plant(cfg: RunConfig) -> PlantBase:
    """Plant of `cfg.machine` with the scenario's mechanics (dyno speed, one mass with its load profile, or two
    masses on a shaft), start speed [rpm] and initial rotor angle [rad]."""
    sc = cfg.scenario
    mech = sc.plant_mechanics(cfg.motor.j)
    return cfg.machine.build_plant(cfg.ts_s, mech, trace_dt_s=cfg.trace_dt_s, theta0_rad=sc.theta0_rad)


__all__ = ["build_plant"]
