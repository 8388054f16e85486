"""Optional gym-electric-motor (GEM) PMSM physical system, built like its ``Finite-CC-PMSM-v0`` env.

Used only by the plant benchmark to time GEM's per-step simulation and compare its currents with
ours. GEM is an optional extra (``pip install pmsm-hil[bench]``); everything here imports it lazily.
"""

from __future__ import annotations

import importlib.util
import math
import warnings
from importlib import metadata
from typing import Any

from pmsm_hil.hil.motor_params import PmsmParams

#: GEM solvers the benchmark can use: key -> description printed with the figures.
GEM_SOLVERS = {
    "default": "ScipyOdeSolver (scipy ode 'dopri5', GEM's default for PMSM envs)",
    "euler": "EulerSolver (one explicit Euler step per Ts)",
}
_BIG = 1e6  # GEM normalises states by limits; make them irrelevant (values are scaled back)


def gem_installed() -> bool:
    """Whether gym-electric-motor is installed: looked up, not imported (its import, with scipy and matplotlib,
    costs ≈ 3 CPU-s)."""
    return importlib.util.find_spec("gym_electric_motor") is not None


def gem_version() -> str | None:
    """Installed gym-electric-motor version, or None when it cannot be imported."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            import gym_electric_motor  # noqa: F401
    except Exception:  # any import failure means "not available" for an optional extra
        return None
    try:
        return metadata.version("gym_electric_motor")
    except metadata.PackageNotFoundError:
        return "unknown"


class GemPmsm:
    """GEM PMSM + finite B6 bridge + constant-speed load + ideal supply, one Ts per ``step``.

    Same components as GEM's ``Finite-CC-PMSM-v0`` environment, without its reward, reference
    and visualisation layers: ``step`` calls the physical system's ``simulate`` only. GEM action
    codes are 4·Sa + 2·Sb + Sc, the same numbering as ours.
    """

    def __init__(self, params: PmsmParams, speed_rpm: float, ts_s: float, solver: str = "default") -> None:
        if solver not in GEM_SOLVERS:
            raise ValueError(f"unknown GEM solver '{solver}' (known: {', '.join(GEM_SOLVERS)})")
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            import gym_electric_motor.physical_systems as gps
            from gym_electric_motor.physical_systems.physical_systems import SynchronousMotorSystem

            limits = {"i": _BIG, "u": _BIG, "omega": _BIG, "torque": _BIG}
            motor = gps.PermanentMagnetSynchronousMotor(
                motor_parameter={"p": params.pole_pairs, "l_d": params.ld, "l_q": params.lq,
                                 "j_rotor": params.j, "r_s": params.rs, "psi_p": params.psi_f},
                limit_values=dict(limits), nominal_values=dict(limits))
            ode_solver = gps.ScipyOdeSolver() if solver == "default" else gps.EulerSolver()
            self._system: Any = SynchronousMotorSystem(
                converter=gps.FiniteB6BridgeConverter(), motor=motor,
                load=gps.ConstantSpeedLoad(omega_fixed=speed_rpm * 2.0 * math.pi / 60.0),
                supply=gps.IdealVoltageSupply(params.vdc), ode_solver=ode_solver, tau=ts_s)
            self._system.reset()
        positions = self._system.state_positions
        self._limits: Any = self._system.limits
        self._i_d = int(positions["i_sd"])
        self._i_q = int(positions["i_sq"])
        self._i_abc = (int(positions["i_a"]), int(positions["i_b"]), int(positions["i_c"]))

    def simulate(self, code: int) -> Any:
        """Advance one Ts with switching state ``code``; returns GEM's normalised state vector."""
        return self._system.simulate(code)

    def step(self, code: int) -> tuple[float, float, tuple[float, float, float]]:
        """Advance one Ts; returns (i_d [A], i_q [A], (i_a, i_b, i_c) [A] as GEM reports them)."""
        state = self._system.simulate(code) * self._limits
        i_a, i_b, i_c = (float(state[k]) for k in self._i_abc)
        return float(state[self._i_d]), float(state[self._i_q]), (i_a, i_b, i_c)
